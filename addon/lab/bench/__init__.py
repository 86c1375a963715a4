"""The benchmarks: one module per area, each with ``KEY``, ``TITLE`` and ``run(output_dir, quick=False) -> BenchResult``.

``lab/report.py`` holds the registry (``report.AREAS``, a tuple of these modules), the cross-area
stability table and the report.md writer.
"""

"""Charts of the shading models and their comparison with Blender's own closures, from real Cycles renders.

    python scripts/brdf_compare.py --out out/brdf [--quick]
    blender -b -P scripts/brdf_compare.py -- --out out/brdf

Writes PNG charts (each model over incidence and view angles; IL Oren-Nayar vs the
Diffuse BSDF; IL Cook-Torrance with F = 1 vs the Glossy BSDF), the CSV tables behind
them and brdf_report.json (node-vs-twin errors, closure differences, render-time ratio
of IL Cook-Torrance over the Principled BSDF).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.core.io.files import write_json
    from addon.lab.bench import shading
    out = os.path.abspath(args.out)
    result = shading.run(out, quick=args.quick)
    write_json(os.path.join(out, "brdf_report.json"), vars(result))
    print(f"brdf_compare: outputs in {out}")
    for name, value in result.figures.items():
        print(f"  {name}: {value:.4g}")
    for row in result.tables["shading_oren_nayar_vs_diffuse"]:
        print(f"  Diffuse BSDF roughness {row['blender_roughness']:g}: best IL sigma {row['best_fit_sigma']:.2f} rad, "
              f"rms {row['best_fit_rms']:.3g} (peak {row['peak']:.3g}); at sigma = roughness rms "
              f"{row['rms_difference']:.3g}")
    for row in result.tables["shading_cook_torrance_vs_glossy"]:
        print(f"  Glossy GGX roughness {row['blender_roughness']:g}: relative rms {row['relative_rms']:.2g}")
    for path in result.charts:
        print(f"  chart: {path}")


def build_parser():
    p = _cli.bench_parser("brdf_compare.py", "Chart the shading models and compare them with Blender's closures.",
                          "out/brdf", "small renders and fewer values, for tests")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)

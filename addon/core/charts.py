"""Charts (matplotlib, Agg backend) and tables (CSV) of the measurements; matplotlib imported lazily.

Every chart the project writes goes through :func:`line_chart` or :func:`scatter_chart`,
so they share one look: labelled axes with units, a legend, a title, 120 dpi PNG.
"""
import csv
import io

import numpy as np

from .io.files import atomic_path, write_bytes


#: What a UI operator reports when it skipped its charts.
MISSING = "matplotlib is needed for charts: charts skipped (tables and images are written)"


def available():
    """True when matplotlib can be imported.

    Inside Blender an extension has numpy and its bundled wheels only, so code reached from a
    UI operator asks this and skips its charts (reporting :data:`MISSING` once); scripts run in
    the project's venv and simply require matplotlib.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _pyplot():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _finish(fig, ax, path, title, xlabel, ylabel, logx, logy):
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0] and ax.get_legend() is None:
        ax.legend(fontsize="small")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    _pyplot().close(fig)
    return str(path)


def line_chart(path, series, title, xlabel, ylabel, logx=False, logy=False, marks=None):
    """``series``: {label: (x, y)}; ``marks``: {label: (x, y)} single highlighted points."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for label, (x, y) in series.items():
        ax.plot(x, y, marker="o", ms=3, label=label)
    for label, (x, y) in (marks or {}).items():
        ax.plot([x], [y], marker="*", ms=14, color="crimson", ls="none", label=label)
    return _finish(fig, ax, path, title, xlabel, ylabel, logx, logy)


def scatter_chart(path, points, title, xlabel, ylabel, logx=False, logy=False, front=True):
    """``points``: {label: (x, y)}; the Pareto front (lower x and y better) is drawn and labelled.

    Labels ending in a number ("gtao 16") share one colour and legend entry per method ("gtao").
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.6))
    labels = list(points)
    xy = np.array([points[k] for k in labels], dtype=float).reshape(-1, 2)
    groups = [_group(k) for k in labels]
    for g in dict.fromkeys(groups):
        idx = [i for i, h in enumerate(groups) if h == g]
        ax.plot(xy[idx, 0], xy[idx, 1], marker="o", ls="none", label=g)
    on_front = pareto_front(xy[:, 0], xy[:, 1]) if (front and len(labels)) else []
    if on_front:
        ax.plot(xy[on_front, 0], xy[on_front, 1], "k--", lw=1, label="Pareto front")
    for i in (on_front if len(labels) > 8 else range(len(labels))):
        ax.annotate(labels[i], tuple(xy[i]), textcoords="offset points", xytext=(4, 4), fontsize="x-small")
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return _finish(fig, ax, path, title, xlabel, ylabel, False, False)


def bar_chart(path, labels, bars, title, xlabel, ylabel):
    """Grouped bars: ``bars`` {series label: values, one per entry of ``labels``}."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    x = np.arange(len(labels))
    width = 0.8 / max(len(bars), 1)
    for i, (name, values) in enumerate(bars.items()):
        ax.bar(x + (i - (len(bars) - 1) / 2) * width, values, width, label=name)
    ax.set_xticks(x, labels)
    return _finish(fig, ax, path, title, xlabel, ylabel, False, False)


def _group(label):
    head, _, tail = label.rpartition(" ")
    return head if head and tail.replace(".", "", 1).isdigit() else label


def pareto_front(cost, error):
    """Indices of the points no other point beats in both cost and error, sorted by cost."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    order = np.lexsort((error, cost))
    front, best = [], np.inf
    for i in order:
        if error[i] < best:
            front.append(int(i))
            best = error[i]
    return front


def write_csv(path, rows):
    """Rows (a list of dicts with the same keys) as CSV, atomically; floats written with repr precision."""
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0].keys()), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    write_bytes(path, buf.getvalue().encode("utf-8"))
    return str(path)

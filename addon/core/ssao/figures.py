"""Images of the SSAO lab: k_A previews, signed error maps and the side-by-side failure grid.

Pure numpy for the pixel images (PNG through core.io.png); matplotlib (Agg,
imported lazily as core.charts does) only for the labelled grid.
"""
import numpy as np

from ..io.files import atomic_path

#: Signed error shown at full colour: |k - k_ref| >= ERROR_LIMIT is saturated.
ERROR_LIMIT = 0.5
SKY_GREY = 0.25


def ao_grey(k_a, mask):
    """k_A in [0, 1] as display grey (linear, 1 = white = open); sky dark grey. Returns (H, W) floats."""
    return np.where(mask, np.clip(np.nan_to_num(k_a, nan=0.0), 0.0, 1.0), SKY_GREY)


def error_rgb(k_a, reference, mask, limit=ERROR_LIMIT):
    """Signed error e = k - k_ref as RGB in [0, 1]: white 0, blue e < 0 (too dark), red e > 0 (too bright).

    Channel values: e > 0 -> (1, 1 - t, 1 - t); e < 0 -> (1 - t, 1 - t, 1), t = min(|e|/limit, 1).
    Sky pixels are dark grey.
    """
    e = np.nan_to_num(np.asarray(k_a, np.float64) - np.asarray(reference, np.float64))
    t = np.clip(np.abs(e) / limit, 0.0, 1.0)
    rgb = np.ones(e.shape + (3,))
    pos, neg = e > 0, e < 0
    rgb[pos, 1] -= t[pos]
    rgb[pos, 2] -= t[pos]
    rgb[neg, 0] -= t[neg]
    rgb[neg, 1] -= t[neg]
    rgb[~np.asarray(mask, bool)] = SKY_GREY
    return rgb


def failure_grid(path, rows, title):
    """A labelled grid of images: ``rows`` = [(row label, [(column title, (H, W) or (H, W, 3) array in [0, 1])])]."""
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    ncols = max(len(cols) for _, cols in rows)
    fig, axes = plt.subplots(len(rows), ncols, figsize=(2.2 * ncols, 2.3 * len(rows)), squeeze=False)
    for r, (label, cols) in enumerate(rows):
        for c in range(ncols):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            if c >= len(cols):
                ax.axis("off")
                continue
            name, img = cols[c]
            ax.imshow(np.clip(img, 0, 1), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            ax.set_title(name, fontsize="x-small")
            if c == 0:
                ax.set_ylabel(label, fontsize="small")
    fig.suptitle(title, fontsize="small")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return str(path)

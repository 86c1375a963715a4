"""Pre-filtered glossy environment map: the normalised Phong lobe summed over the lat-long map."""
import numpy as np

from .irradiance import clamped_cosine, quadrature
from .latlong import latlong_directions


def phong_lobe(r, l, n):
    """((n + 1)/2π) (r·l)⁺ⁿ: the normalised Phong lobe around the reflection direction r (integrates to 1)."""
    return (n + 1) / (2 * np.pi) * clamped_cosine(r, l) ** n


def prefilter_phong(env, n, width=64, max_width=256, chunk=256):
    """Pre-filtered map G(r) = ∫ L(l) ((n+1)/2π) (r·l)⁺ⁿ dl as a lat-long map (width/2, width, C).

    n = 1 gives E(r)/π; a constant environment L gives L for every n. The
    environment is box-filtered to at most ``max_width`` columns: keep its pixel
    well below the lobe width (about 1/sqrt(n) radians).
    """
    dirs, weighted = quadrature(env, max_width)
    c = weighted.shape[1]
    r = latlong_directions(width // 2, width).reshape(-1, 3)
    out = np.empty((r.shape[0], c))
    for s in range(0, r.shape[0], chunk):
        out[s:s + chunk] = phong_lobe(r[s:s + chunk, None, :], dirs[None], n) @ weighted
    return out.reshape(width // 2, width, c)

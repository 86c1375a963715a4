"""Closed forms used as test oracles and reference values: no approximation in them.

SSAO: the disk areas behind the open fraction of a corner (REFERENCE.md §3 with an AO distance R).
"""
import numpy as np


def disk_segment(c):
    """Area of the unit disk where x > c (0 <= c <= 1): acos c - c√(1 - c²)."""
    c = np.clip(c, 0.0, 1.0)
    return np.arccos(c) - c * np.sqrt(1.0 - c * c)


def disk_quadrant(a, b):
    """Area of the unit disk where x > a and y > b (a, b >= 0): ∫_a^t (√(1 - x²) - b) dx, t = √(1 - b²)."""
    a, b = np.clip(a, 0.0, 1.0), np.clip(b, 0.0, 1.0)
    top = np.sqrt(np.clip(1.0 - b * b, 0.0, 1.0))

    def g(t):      # ∫ √(1 - x²) dx
        return 0.5 * (t * np.sqrt(np.clip(1 - t * t, 0, 1)) + np.arcsin(np.clip(t, -1, 1)))
    return np.where(a < top, g(top) - g(a) - b * (top - a), 0.0)


def corner_k_a(a, b):
    """k_A, AO distance R, of a point at distances a R and b R from two perpendicular infinite planes
    meeting at a right angle to its own surface (a room's floor by two walls; a = ∞ for one wall).

    A cosine-weighted direction projects uniformly onto the unit disk of the tangent plane
    (Nusselt); the plane at distance d blocks, within R, exactly the directions whose component
    toward it exceeds d/R: a disk segment. Two planes block the union of two segments:
    k_A = 1 - (seg(a) + seg(b) - quad(a, b))/π. R -> ∞ gives REFERENCE.md §3's 1/2 (one wall
    through the point) and 1/4 (the corner).
    """
    return 1.0 - (disk_segment(a) + disk_segment(b) - disk_quadrant(a, b)) / np.pi

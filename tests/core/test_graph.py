"""core.graph.components against a breadth-first search: every node labelled by the least node of its part, on
random graphs, isolated nodes, self-loops and a long shuffled chain (where label propagation needs a round per node)."""
import collections

import numpy as np

from addon.core.graph import components


def _bfs(a, b, n):
    """The least node of each node's part, by breadth-first search over the edges."""
    near = collections.defaultdict(list)
    for x, y in zip(a, b):
        near[int(x)].append(int(y))
        near[int(y)].append(int(x))
    out = np.full(n, -1)
    for start in range(n):
        if out[start] >= 0:
            continue
        out[start], todo = start, [start]
        while todo:
            for y in near[todo.pop()]:
                if out[y] < 0:
                    out[y] = start
                    todo.append(y)
    return out


def test_random_graphs_match_a_breadth_first_search():
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(1, 120))
        e = int(rng.integers(0, 2 * n))
        a, b = rng.integers(0, n, e), rng.integers(0, n, e)
        assert np.array_equal(components(a, b, n), _bfs(a, b, n))


def test_no_edges_and_self_loops_leave_every_node_alone():
    assert np.array_equal(components([], [], 5), np.arange(5))
    assert np.array_equal(components([0, 3, 3], [0, 3, 3], 4), np.arange(4))


def test_a_long_shuffled_chain_is_one_part_in_few_rounds():
    n = 20_000
    order = np.random.default_rng(3).permutation(n)
    edges = np.random.default_rng(4).permutation(n - 1)
    a, b = order[edges], order[edges + 1]
    assert np.array_equal(components(a, b, n), np.zeros(n, np.int64))
    assert np.array_equal(components(a, b, n + 3)[n:], np.arange(n, n + 3))

"""Charts are real PNGs; the Pareto front is the set no other point beats."""
import csv

import numpy as np
import pytest

from addon.core import charts


def test_pareto_front_matches_brute_force():
    rng = np.random.default_rng(3)
    cost, err = rng.random(40), rng.random(40)
    dominated = {i for i in range(40) for j in range(40)
                 if cost[j] <= cost[i] and err[j] <= err[i] and (cost[j] < cost[i] or err[j] < err[i])}
    assert set(charts.pareto_front(cost, err)) == set(range(40)) - dominated


def test_charts_and_csv_are_written(tmp_path):
    pytest.importorskip("matplotlib")
    p = charts.line_chart(tmp_path / "l.png", {"a": ([1, 2, 4], [1.0, 0.5, 0.25])}, "t", "x", "y",
                          logx=True, logy=True, marks={"best": (2, 0.5)})
    q = charts.scatter_chart(tmp_path / "s.png", {"m1": (1.0, 2.0), "m2": (2.0, 1.0), "m3": (3.0, 3.0)}, "t", "s", "e")
    for path in (p, q):
        assert open(path, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    charts.write_csv(tmp_path / "t.csv", [{"method": "a", "rmse": 0.125}, {"method": "b", "rmse": 0.5}])
    rows = list(csv.DictReader(open(tmp_path / "t.csv")))
    assert [float(r["rmse"]) for r in rows] == [0.125, 0.5]

"""Edges of the parameter space, reduced: every row ends stable or stopped by the guard with a
message; never NaN in the results, a hang or an exception.

A handful of rows of ``runout study extremes`` on the tiny column with apic-affine, 0.03 s each
(about 30 s in all on 2 CPU cores); the report is written too.
"""

import pytest

from studies import extremes

pytestmark = pytest.mark.slow

LABELS = {
    "5 x critical", "E = 1e+10 Pa", "nu = 0.49", "16 per cell", "f64",
    "falling through an open bottom", "thrown through an open right side",
}


def test_edge_rows_are_stable_or_stopped_with_a_message(tmp_path):
    rows = [r for r in extremes.rows() if r.label in LABELS]
    assert len(rows) == len(LABELS)
    result = extremes.run(tmp_path, quick=True, selection=rows, schemes=("apic-affine",), duration_s=0.03)
    table = result.data["rows"]
    assert len(table) == len(LABELS)
    for row in table:
        assert row["outcome"] in ("stable", "stopped by the guard"), row
        if row["outcome"] == "stopped by the guard":
            assert row["message"].startswith("unstable:") and "critical" in row["message"], row
    by = {r["row"]: r for r in table}
    assert by["5 x critical"]["outcome"] == "stopped by the guard"
    assert by["thrown through an open right side"]["lost"] > 0
    assert result.passed
    assert result.report.is_file() and (tmp_path / "extremes.csv").is_file()

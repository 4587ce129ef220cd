"""Every shipped example gives the frames it gave before: a fingerprint of every frame array.

``tests/data/example_frames.json`` holds, per example, frame and array, the array's dtype, its
sum and the sum of its magnitudes (float64). Integer arrays must match exactly; a float array's
sum may move by ``FLOAT_RTOL`` (per field, default ``FLOAT_RTOL_DEFAULT``) of the sum of its
magnitudes. The tolerances lie between two measurements: summing in another order (the serial
against the split scatter, the kind of difference another CPU's compiled code makes) moves the
sums by at most 4e-6 of the magnitude (the sand column's stress; its plastic strain 5e-6, which
another machine has moved by 2e-5: plastic strain at the onset of yield is the most sensitive
array), while a friction angle 0.01 degrees higher moves them by 1e-4 (stresses 6e-4). So a
change of the physics fails here and another machine does not. That a run repeats bit for bit on
one machine is tested below on series.csv. Each example runs 200 to 400 steps with its own
settings. A change that alters the numbers of a scene fails here; if the change is meant (a
physics fix), write the fingerprints again and say so in the commit. To check that a
refactoring keeps the frames bit for bit, ``write`` the fingerprints before and after it on one
machine and compare the files: a float64 sum sees a change in the last bit of any float32 value
but the tiniest.

Write them: ``python tests/regression/test_examples_frames.py write [COMMIT]``.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
DIGESTS = REPO / "tests" / "data" / "example_frames.json"
#: a float array's sum may move by this fraction of the sum of its magnitudes (see above)
FLOAT_RTOL_DEFAULT = 5e-5
FLOAT_RTOL = {"plastic_strain": 2e-4}
#: example -> overrides that keep its run short (a few hundred steps, a few frames)
SHORT = {
    "tiny_column": ["stages.1.duration_s=0.04", "output.interval_s=0.01"],
    "sand_column": ["stages.0.duration_s=0.004", "output.interval_s=0.001"],
    "slope_sun_song_2015": ["stages.0.duration_s=0.2", "stages.1.duration_s=0.1", "stages.2.duration_s=0.1",
                            "output.interval_s=0.1"],
    "bui2008_aluminium_bars": ["stages.1.duration_s=0.004", "output.interval_s=0.002"],
    "debris_barrier": ["stages.0.duration_s=0.3", "stages.0.min_duration_s=0.1", "output.interval_s=0.1"],
}


def frame_digests(example: str, out_dir: Path) -> list[dict[str, list]]:
    """Run the shortened example into ``out_dir``; per frame, per array ``[dtype, sum, sum of
    magnitudes]`` (float64 sums)."""
    sys.path.insert(0, str(REPO))
    from projects.document import load_project
    from projects.results import Results
    from projects.runner import run_project

    project = load_project(REPO / "projects" / "examples" / f"{example}.toml", SHORT[example])
    result = run_project(project, out_dir)
    assert result.status == "completed", result.message
    results = Results(out_dir)
    digests = []
    for i in range(len(results)):
        frame = results.frame(i)
        digests.append({name: [str(np.asarray(a).dtype), float(np.sum(a, dtype=np.float64)),
                               float(np.sum(np.abs(a), dtype=np.float64))]
                        for name, a in sorted(frame.items())})
    return digests


def mismatches(got: list[dict[str, list]], expected: list[dict[str, list]]) -> list[str]:
    """What differs between two runs' fingerprints, one line each (empty: the same run)."""
    if len(got) != len(expected):
        return [f"{len(got)} frames, expected {len(expected)}"]
    out = []
    for i, (g, e) in enumerate(zip(got, expected)):
        if sorted(g) != sorted(e):
            out.append(f"frame {i}: arrays {sorted(g)}, expected {sorted(e)}")
            continue
        for name in e:
            (gt, gs, _), (et, es, ea) = g[name], e[name]
            exact = np.issubdtype(np.dtype(et), np.integer) or et == "bool"
            allowed = 0.0 if exact else FLOAT_RTOL.get(name, FLOAT_RTOL_DEFAULT) * max(ea, 1e-30)
            if gt != et or abs(gs - es) > allowed:
                out.append(f"frame {i} {name}: {gt} sum {gs!r}, expected {et} {es!r} (allowed {allowed:.2g})")
    return out


@pytest.mark.slow
@pytest.mark.parametrize("example", sorted(SHORT))
def test_example_frames_are_unchanged(example, tmp_path):
    expected = json.loads(DIGESTS.read_text())["frames"][example]
    assert mismatches(frame_digests(example, tmp_path / example), expected) == []


def test_the_fingerprint_comparison_sees_a_change_above_the_tolerance_only():
    base = [{"stress": ["float32", 1000.0, 2.0e6], "active": ["int8", 500.0, 500.0]}]
    drift = [{"stress": ["float32", 1000.0 + 0.5 * FLOAT_RTOL_DEFAULT * 2.0e6, 2.0e6], "active": ["int8", 500.0, 500.0]}]
    moved = [{"stress": ["float32", 1000.0 + 2.0 * FLOAT_RTOL_DEFAULT * 2.0e6, 2.0e6], "active": ["int8", 500.0, 500.0]}]
    lost = [{"stress": ["float32", 1000.0, 2.0e6], "active": ["int8", 499.0, 499.0]}]
    assert mismatches(drift, base) == []
    assert [line.split(":")[0] for line in mismatches(moved, base)] == ["frame 0 stress"]
    assert [line.split(":")[0] for line in mismatches(lost, base)] == ["frame 0 active"]
    assert mismatches(base + base, base) == ["2 frames, expected 1"]


@pytest.mark.slow
def test_the_series_of_a_run_repeats_bit_for_bit(tmp_path):
    """series.csv (energies, momenta, counts per frame) of two runs of the same project is the same
    file, as the frames are: with the plain-add scatters the diagnostics' sums run in particle
    order (before, in parallel with atomic adds, the kinetic energy of the 20,000-particle scene
    differed in the sixth digit from run to run)."""
    sys.path.insert(0, str(REPO))
    from projects.document import load_project
    from projects.runner import run_project

    texts = []
    for k in range(2):
        project = load_project(REPO / "projects" / "examples" / "bui2008_aluminium_bars.toml",
                               SHORT["bui2008_aluminium_bars"] + ["numerics.advanced.scatter=split"])
        out = tmp_path / f"run{k}"
        assert run_project(project, out).status == "completed"
        texts.append((out / "series.csv").read_bytes())
    assert texts[0] == texts[1]


if __name__ == "__main__" and len(sys.argv) >= 2 and sys.argv[1] == "write":
    import tempfile

    commit = sys.argv[2] if len(sys.argv) > 2 else "working tree"
    with tempfile.TemporaryDirectory() as tmp:
        data = {"commit": commit, "frames": {name: frame_digests(name, Path(tmp) / name) for name in sorted(SHORT)}}
    DIGESTS.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {DIGESTS}")

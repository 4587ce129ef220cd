"""Every shipped example gives the frames it gave before (a fingerprint of every frame array).

The digests in ``tests/data/example_frames.json`` were first written at 2c3ebaa, before the
one-run-path refactoring (runs as processes, checkpoints, ``resolve``), and every example gave the
same frames after it. The contact law of issue 11 then changed the physics at closed walls (the
friction no longer over-counted): the digests were written again after it, at the commit named in
the file; the sand column, whose walls do not touch it in these steps, kept its digests. Then the mirror
walls' friction (the ghost's normal impulse on a friction wall brings Coulomb friction with it,
issue 11) changed the two examples with a friction floor, the aluminium bars and the tiny column,
written again at 3508e96; the sand column and the slope (fixed and slip walls) kept theirs. Then the k0
stage's overburden by each particle's own bar of material instead of grid-cell columns (exact for
lattices at any alignment; a structure face between node lines had its particle line at half its
overburden) changed the two examples with a k0 stage, the aluminium bars and the tiny column, in the
last bits (initial stresses 1e-12 of the largest apart): written again; the sand column and the slope
(no k0 stage) kept theirs. Then friction decided by wall column (the wall node and its ghosts one
contact point, issue 11, session 11) changed the two examples with a friction floor again, the
aluminium bars and the tiny column, written again; the sand column and the slope kept theirs. Then
local damping left off the contact nodes (issue 11, session 12) changed the one example with a
damped gravity stage, the slope, written again; the others kept theirs. Then the lattice seeding
clipped at the bodies' outlines (a point at the centroid of each body's part of a cut sub-cell,
session 13) changed the one example with an outline off the sub-cell lines, the slope, written
again; the others (grid-aligned rectangles) kept theirs bit for bit. Session 16 added the
check-dam example, then compiled the CPU kernels without Taichi's advanced-optimization passes
(seven times faster to compile, solver.runtime): every example's frames moved in the last bits
of f32 (9e-8 m/s in the first frame of the check dam), written again. Session 17 stopped the walls'
mirror image from pulling the ghost back and gave its friction to the wall column (issue 11):
the three examples whose material touches a friction or slip side in these steps (aluminium bars,
slope, tiny column) written again; the sand column and the check dam kept theirs. Session 19 found four examples' digests different on its machine with the code unchanged (the landed commit d4e484d gives
the new digests there too; numpy 2.4.5 and 2.4.6 alike: the CPU's code from Taichi's LLVM or another
library, in the last bits): written again on the machine CI runs on. Each example runs 200 to 400 steps with its own settings and the
scatter ``auto`` picks on this machine (serial below 10,000 particles, split above, on a CPU with
few threads: both repeat bit for bit). A change that alters the numbers of a scene fails here; if
the change is meant (a physics fix), write the digests again and say so in the commit.
Session 22 found the digests different again on a new machine with the code unchanged (the
commit before session 21 gives the same new digests there), while CI runs on whatever machine
the session has: bit-for-bit digests test the machine as much as the code. The file now holds
a fingerprint per frame and array instead (its dtype, its sum and the sum of its magnitudes, in
float64); integer arrays must match exactly, float arrays within ``FLOAT_RTOL`` of the array's
magnitude. Measured on the examples (session 22): summing in another order (the serial against
the split scatter, the kind of difference another CPU's code makes) moves the sums by at most
5e-7 of the magnitude (stresses of the tiny column; 2e-8 to 1e-7 for the other arrays), a
friction angle 0.01 degrees higher by 1e-4 (stresses 6e-4): the tolerance lies between. That a
run repeats bit for bit on one machine is tested below on series.csv. To check that a refactoring keeps the
frames bit for bit, ``write`` the fingerprints before and after it on one machine and compare the
files: a float64 sum sees a change in the last bit of any float32 value but the tiniest.

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
FLOAT_RTOL = 1e-5
#: example -> overrides that keep its run short (a few hundred steps, a few frames)
SHORT = {
    "tiny_column": ["stages.1.duration_s=0.04", "output.interval_s=0.01"],
    "sand_column": ["stages.0.duration_s=0.004", "output.interval_s=0.001"],
    "slope_sun_song_2015": ["stages.0.duration_s=0.02", "stages.1.duration_s=0.01", "stages.2.duration_s=0.01",
                            "output.interval_s=0.01"],
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
            allowed = 0.0 if exact else FLOAT_RTOL * max(ea, 1e-30)
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
    drift = [{"stress": ["float32", 1000.0 + 0.5 * FLOAT_RTOL * 2.0e6, 2.0e6], "active": ["int8", 500.0, 500.0]}]
    moved = [{"stress": ["float32", 1000.0 + 2.0 * FLOAT_RTOL * 2.0e6, 2.0e6], "active": ["int8", 500.0, 500.0]}]
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

"""The benchmark harness on a tiny configuration: structure and sanity of the numbers, no timing asserts."""

import json
import math

import pytest

from benchmarks.bench import (
    COMPONENT_VARIANTS,
    NOT_MEASURED_NO_GPU,
    WATER_VARIANT,
    YARDSTICK,
    BenchConfig,
    BenchError,
    collapse_scene,
    markdown_report,
    paired_ratio,
    report_tables,
    run_bench_config,
)

TINY = BenchConfig(
    startup_runs=0,  # start-up spawns runout runs with a cold kernel cache: a bench row, not a test
    particle_counts=(200,), precisions=("f32",), schemes=("apic", "apic-affine"), archs=("cpu", "gpu"),
    gpu_particle_counts=(200,), batch_s=0.01, rounds=1, warmup_steps=2, min_steps=2, max_steps=4,
    profile_particles=(200,), profile_steps=3, empty_domain_particles=200, empty_domain_schemes=("apic-affine",),
    stall_particles=200, stall_duration_s=0.002, stall_interval_s=0.001, stall_rounds=1,
    envelope_particles=200, envelope_every_steps=2, envelope_steps=4,
)


def _positive(value):
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "bench.json"
    result = run_bench_config(TINY, out)
    return result, out


def test_scene_is_the_aluminium_bar_block_scaled_to_the_particle_count():
    config, particles = collapse_scene(20_000)
    assert len(particles) == 20_000
    assert config.grid.cell_size_m == pytest.approx(0.002)
    assert config.numerics.time_step_s == pytest.approx(2e-5)
    assert config.grid.cells == (400, 75)
    assert config.materials[0].model == "drucker-prager"
    long, _ = collapse_scene(20_000, length_factor=2.0)
    assert long.grid.cells == (800, 75)
    small, few = collapse_scene(1_000)
    assert 900 <= len(few) <= 1_100
    assert few.positions_m[:, 0].max() < 0.2 and few.positions_m[:, 1].max() < 0.1


def test_paired_ratio_is_the_median_of_per_round_ratios():
    assert paired_ratio([2.0, 9.0, 3.0], [1.0, 3.0, 1.0]) == pytest.approx(3.0)


def test_bad_configuration_is_refused():
    with pytest.raises(BenchError, match="unknown scheme"):
        BenchConfig(schemes=("flip",))
    with pytest.raises(BenchError, match="precision"):
        BenchConfig(precisions=("f16",))


def test_throughput_rows_hold_positive_rates_and_ratios(bench):
    result, _ = bench
    rows = result["throughput"]
    variants = {r["variant"] for r in rows if r["arch"] == "cpu"}
    assert variants == {YARDSTICK, "apic", "apic-affine", *COMPONENT_VARIANTS}
    assert WATER_VARIANT in COMPONENT_VARIANTS
    for variant in COMPONENT_VARIANTS:  # the cost of each component, timed beside the plain engine
        assert _positive(next(r for r in rows if r["variant"] == variant)["ratio_to_dry"]), variant
    assert all(r["ratio_to_dry"] is None for r in rows if r["variant"] not in COMPONENT_VARIANTS)
    for row in rows:
        assert row["precision"] == "f32" and row["particles"] == 200
        for key in ("particle_steps_per_s", "ratio_to_yardstick", "ratio_to_apic", "ratio_to_yardstick_best",
                    "ratio_to_apic_best", "step_time_s", "bytes_per_particle", "best_s"):
            assert _positive(row[key]), (row["variant"], key, row[key])
        assert row["steps"] >= TINY.min_steps and row["rounds"] == len(row["times_s"]) == TINY.rounds
        assert row["finite"] is True
        assert row["particle_bytes_per_particle"] + row["grid_bytes_per_particle"] <= row["bytes_per_particle"] + 1e-9
    yard = next(r for r in rows if r["variant"] == YARDSTICK)
    assert yard["ratio_to_yardstick"] == pytest.approx(1.0)
    apic = next(r for r in rows if r["variant"] == "apic")
    assert apic["ratio_to_apic"] == pytest.approx(1.0)


def test_engine_memory_counts_particle_and_grid_fields(bench):
    row = next(r for r in bench[0]["throughput"] if r["variant"] == "apic-affine")
    # at least x, x0, v, C, s, m, rho, eps_p in f32: 2+2+2+4+4+1+1+1 floats
    assert row["particle_bytes_per_particle"] >= 17 * 4
    assert row["grid_bytes_per_particle"] > 0


def test_gpu_is_measured_or_marked_not_measured(bench):
    result, _ = bench
    gpu_rows = [r for r in result["throughput"] if r["arch"] == "gpu"]
    if result["machine"]["gpu_available"]:
        assert gpu_rows or any(m["arch"] == "gpu" for m in result["not_measured"])
    else:
        assert not gpu_rows
        assert {"arch": "gpu", "reason": NOT_MEASURED_NO_GPU} in result["not_measured"]


def test_profile_splits_the_step_into_stages_and_overhead(bench):
    (prof,) = bench[0]["profile"]
    from benchmarks.bench import SCATTER_VARIANTS

    # beside the scatter the engine picks, the profile shows apic-affine with the other ones
    chosen = prof["variants"]["apic-affine"]["scatter"]
    extra = {name for name, s in SCATTER_VARIANTS.items() if s != chosen}
    for name in extra:
        assert prof["variants"][name]["scatter"] == SCATTER_VARIANTS[name]
    assert set(prof["variants"]) == {YARDSTICK, "apic", "apic-affine"} | extra
    affine = prof["variants"]["apic-affine"]
    apic = prof["variants"]["apic"]
    # stage names are the engine's recipe (Engine.recipe), profiled one launch per stage
    assert any("P2G" in stage for stage in affine["stages_s_per_step"])
    assert any("P2G" in stage for stage in apic["stages_s_per_step"])
    assert len(apic["stages_s_per_step"]) >= 3
    for v in prof["variants"].values():
        assert _positive(v["wall_s_per_step"]) and _positive(v["kernel_s_per_step"])
        assert v["python_s_per_step"] >= 0 and 0 <= v["python_fraction"] < 1
        assert v["kernel_s_per_step"] == pytest.approx(sum(v["stages_s_per_step"].values()))
    assert affine["tasks_per_step"] < apic["tasks_per_step"]  # four stages against six
    assert prof["constitutive_alone_s_per_step"] >= 0


def test_empty_domain_and_output_stall_give_ratios(bench):
    result, _ = bench
    empty = result["empty_domain"]
    assert set(empty["variants"]) == {"apic-affine", YARDSTICK}
    for v in empty["variants"].values():
        assert _positive(v["ratio"])
        assert v["grid_cells_doubled"][0] == 2 * v["grid_cells"][0]
        assert v["bytes_per_particle_doubled"] > v["bytes_per_particle"]
    stall = result["output_stall"]
    assert _positive(stall["ratio"])
    assert stall["frames_written"] >= 3
    for key in ("copy_s_per_frame", "encode_s_per_frame", "estimated_ratio"):
        assert _positive(stall[key]), key
    assert stall["write_frame_s"] >= 0 and stall["close_s"] >= 0
    assert stall["steps_with_frames"] > 0 and stall["steps_without_frames"] > 0


def test_targets_and_reports(bench):
    result, out = bench
    names = [t["name"] for t in result["targets"]]
    # throughput (2), one ratio per component variant (water, softening, volumetric averaging),
    # empty domain, memory, output stall, hazard envelopes, GPU throughput and start-up rows
    for expected in ("apic-affine / apic throughput", "apic-affine (Drucker-Prager) / yardstick",
                     "apic-affine with ground water / dry throughput",
                     "apic-affine, softening / apic-affine throughput",
                     "apic-affine, volumetric averaging / apic-affine throughput",
                     "step time, domain twice as long / normal", "solver memory per particle (f32, fields)",
                     "GPU particle-steps/s at 1e6 f32"):
        assert expected in names, expected
    assert len(names) == len(set(names)) == 11
    for t in result["targets"]:
        assert t["met"] in (True, False, None)
        assert (t["value"] is None) == (t["met"] is None)
    on_disk = json.loads(out.read_text())
    assert on_disk["throughput"] == json.loads(json.dumps(result["throughput"]))
    md = out.with_suffix(".md").read_text()
    assert md == markdown_report(result)
    assert len(result["load_average"]["start"] or [0, 0, 0]) == 3
    assert "| arch | prec | particles |" in md and "### Targets" in md
    titles = [title for title, _, _ in report_tables(result)]
    assert any(t.startswith("Profile") for t in titles) and any(t.startswith("Output stall") for t in titles)


def test_profiler_task_names_map_to_stages():
    from benchmarks.bench import _recipe_stages, _stage_of

    records = [("_stage_kernel_c9_0_kernel_0_serial", 0.0), ("_stage_kernel_c9_0_kernel_1_range_for", 1.0),
               ("_stage_kernel_c9_1_kernel_0_range_for", 2.0), ("_stage_kernel_c9_0_kernel_0_serial", 0.0)]
    named = _recipe_stages(records, ("reset grid", "G2P"))
    assert named == {"_stage_kernel_c9_0": ("reset grid", "reset grid"), "_stage_kernel_c9_1": ("G2P", "G2P")}
    assert _stage_of("_substep_c12_0_kernel_2_range_for", YARDSTICK) == ("_substep (loop 2)", "grid pass")
    assert _stage_of("_step_c5_0_kernel_1_range_for", "apic") == ("_step (loop 1)", "other: _step")
    assert _stage_of("weird", "apic") == ("weird", "other")


def test_hazard_envelope_cost_is_a_fraction_of_the_step(bench):
    result, _ = bench
    env = result["hazard_envelopes"]
    assert env["every_steps"] == 2 and env["batches"] == 2
    assert _positive(env["step_time_s"]) and _positive(env["update_time_s"]) and _positive(env["fraction"])
    assert any(t["name"].startswith("hazard envelopes") for t in result["targets"])
    assert "Hazard envelopes" in markdown_report(result)

"""The fusion paper's experiments with their runs advancing together (run_batch) against the same
runs one at a time (run_one, the unbatched step functions looped), and the runner's --batch:

* every non-timing field of a run's record is the same bits for batches of 6, 1 × 6 and 2 + 4;
* against run_one, every field outside DMF's own recursion is equal to PER_RUN_RTOL. DMF's recursion
  (its errors, its distance from CMF, the one-step gap and its bound at DMF's central prediction)
  computes eq. 35 by the block route in the batch and the per-step route in run_one: two roundings of
  one recursion that amplifies rounding (the per-run record's own DMF and CMF, mathematically the
  same filter on full-rank runs, differ by up to 2e-9 relative after a few steps). There the batch is
  compared with the per-run record's own rounding spread: within ten times the largest relative
  |DMF − CMF| of that run (the two differences are independent draws of the same rounding, measured
  at most 2.2 times apart), and each step's verdict (gap within its bound) the same;
* reproduce with --batch 1, --batch 4 and --workers 2 writes the same results.json, for the fusion
  experiments and for the particle methods' (pff1d, bearing, tbd) through their own run_batch."""

import json

import numpy as np
import pytest

from gpfverify.contract.serial import to_json
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion import ungm1d_experiment as ungm1d
from gpfverify.experiments.runner import run_experiment, untimed, without_timing
from gpfverify.tolerances import PER_RUN_RTOL

SEEDS = [np.random.SeedSequence(7, spawn_key=(i,)) for i in range(6)]
#: how far apart two independent roundings of DMF's recursion may fall, in units of one of them
#: (module docstring)
ROUNDING_SPREAD = 10.0
DMF_FIELDS = ("recursive_gap", "one_step_gap", "one_step_gap_rel", "gap_size", "gap_bound", "audit")


def _records(module, params, seeds):
    return [untimed(to_json(r)) for r in module.run_batch(params, seeds)]


@pytest.fixture(scope="module")
def ct2d_runs():
    params = ct2d.Params(kappa=30, test_steps=6)
    return params, _records(ct2d, params, SEEDS)


@pytest.mark.slow
def test_ct2d_runs_are_the_same_for_every_batch(ct2d_runs):
    params, full = ct2d_runs
    assert [_records(ct2d, params, [s])[0] for s in SEEDS] == full
    assert _records(ct2d, params, SEEDS[:2]) + _records(ct2d, params, SEEDS[2:]) == full


@pytest.mark.slow
def test_ungm1d_runs_are_the_same_for_every_batch():
    params = ungm1d.Params(train=40, test_steps=5)
    full = _records(ungm1d, params, SEEDS[:4])
    assert _records(ungm1d, params, SEEDS[:1]) + _records(ungm1d, params, SEEDS[1:4]) == full


def _families(record):
    return record.get("families") or {f"{k}/{f}": v for k, s in record["settings"].items()
                                      for f, v in s["families"].items()}


def _assert_close(got, ref, where: str):
    """Equal structure, equal non-floats, floats within PER_RUN_RTOL of the largest magnitude of the
    array they belong to (a vector or matrix: an off-diagonal entry rounds relative to its matrix)."""
    if isinstance(ref, dict):
        assert got.keys() == ref.keys(), where
        for key in ref:
            _assert_close(got[key], ref[key], f"{where}/{key}")
    elif isinstance(ref, list) and ref and all(isinstance(v, (float, list)) for v in ref) and _numeric(ref):
        a, b = np.array(got, dtype=float), np.array(ref, dtype=float)
        assert a.shape == b.shape, where
        assert np.all(np.abs(a - b) <= PER_RUN_RTOL * np.max(np.abs(b), initial=0.0)), (where, np.max(np.abs(a - b)))
    elif isinstance(ref, list):
        assert len(got) == len(ref), where
        for g, r in zip(got, ref):
            _assert_close(g, r, where)
    elif isinstance(ref, float):
        assert abs(got - ref) <= PER_RUN_RTOL * abs(ref), (where, got, ref)
    else:
        assert got == ref, (where, got, ref)


def _numeric(value) -> bool:
    """Whether ``value`` is a float or a (nested, rectangular) list of floats."""
    if isinstance(value, float):
        return True
    return isinstance(value, list) and bool(value) and all(_numeric(v) for v in value)


def _assert_family_close(batch: dict, alone: dict):
    dmf = [k for k in batch["sq_err"] if k.startswith("DMF-")][0]
    cmf = dmf.replace("DMF-", "CMF-")
    for metric in ("sq_err", "maha"):
        for method, values in alone[metric].items():
            got, ref = np.array(batch[metric][method]), np.array(values)
            if method != dmf:
                np.testing.assert_allclose(got, ref, rtol=PER_RUN_RTOL, err_msg=f"{metric} {method}")
                continue
            if not all(alone["condition_holds"]):
                continue  # DMF and CMF differ in earnest there: no rounding spread to compare with
            spread = np.max(np.abs(ref - np.array(alone[metric][cmf])) / np.array(alone[metric][cmf]))
            assert np.all(np.abs(got - ref) <= max(PER_RUN_RTOL, ROUNDING_SPREAD * spread) * ref), (metric, method)
    for field, values in alone.items():
        if field not in ("sq_err", "maha") and field not in DMF_FIELDS:
            _assert_close(batch[field], values, field)
    reproduced = np.array(batch["gap_size"]) <= np.array(batch["gap_bound"])
    np.testing.assert_array_equal(reproduced, np.array(alone["gap_size"]) <= np.array(alone["gap_bound"]))


@pytest.mark.slow
def test_ct2d_batch_equals_the_runs_one_at_a_time(ct2d_runs):
    params, full = ct2d_runs
    for seed, batch in zip(SEEDS, full):
        alone = untimed(to_json(ct2d.run_one(params, seed)))
        assert batch["hyperparameters"] == alone["hyperparameters"]
        for name, family in _families(alone).items():
            _assert_family_close(_families(batch)[name], family)


@pytest.mark.slow
def test_reproduce_is_the_same_for_every_batch_and_worker_count(tmp_path):
    params = ct2d.Params(kappa=30, test_steps=4)
    outs = []
    for name, kwargs in (("b1", {"batch": 1}), ("b4", {"batch": 4}), ("default", {})):
        outs.append(without_timing(run_experiment(ct2d, params, 5, 3, tmp_path / name, **kwargs)))
    from gpfverify.experiments.runner import make_executor
    with make_executor(2) as executor:
        outs.append(without_timing(run_experiment(ct2d, params, 5, 3, tmp_path / "w2", executor=executor, batch=2)))
    texts = [json.dumps(o, sort_keys=True) for o in outs]
    assert texts[1:] == texts[:1] * 3
    saved = json.loads((tmp_path / "b4" / "runs" / "run-000004.json").read_text())
    assert saved["batch_size"] == 1 and saved["status"] == "ok"


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["pff1d", "bearing", "tbd"])
def test_reproduce_of_a_particle_experiment_is_the_same_for_every_batch_and_worker_count(experiment, tmp_path):
    """The runner hands the particle experiments' run_batch B runs at a time (5 runs: batches of 1,
    of 3 + 2, and of 2 + 2 + 1 over two worker processes): the same results.json every time."""
    from gpfverify.experiments.runner import make_executor
    from tests.test_particle_runs import _experiment_cases

    module, params = _experiment_cases()[experiment]
    outs = [without_timing(run_experiment(module, params, 5, 2, tmp_path / f"b{b}", batch=b, show_progress=False))
            for b in (1, 3)]
    with make_executor(2) as executor:
        outs.append(without_timing(run_experiment(module, params, 5, 2, tmp_path / "w2", executor=executor, batch=2,
                                                  show_progress=False)))
    texts = [json.dumps(o, sort_keys=True) for o in outs]
    assert texts[1:] == texts[:1] * 2
    saved = [json.loads((tmp_path / "b3" / "runs" / f"run-{i:06d}.json").read_text())["batch_size"] for i in range(5)]
    assert saved == [3, 3, 3, 2, 2]


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["pff1d", "bearing", "tbd"])
def test_timing_claims_say_runs_shared_a_batch_only_when_the_saved_runs_did(experiment, tmp_path):
    """The words on how a timing claim's seconds were measured follow the saved runs' batch sizes:
    at --batch 1 every run was timed alone and no claim says its runs shared a batch's time; at
    --batch 3 every timing claim says so, once, in the experiment's own words."""
    from gpfverify.experiments.batching import batching_caveat
    from tests.test_particle_runs import _experiment_cases

    module, params = _experiment_cases()[experiment]
    words = batching_caveat(module)
    for batch, expected in ((1, 0), (3, 1)):
        results = run_experiment(module, params, 5, 2, tmp_path / f"b{batch}", batch=batch, show_progress=False)
        assert results["machine_load"]["runs_batched"] == (0 if batch == 1 else 5)
        assert results["timing_claims"], "the experiment's timing claims were not judged"
        assert [c["caveats"].count(words) for c in results["timing_claims"]] == [expected] * len(results["timing_claims"])


@pytest.mark.slow
def test_resume_finishes_a_batched_run_with_the_same_results(tmp_path):
    params = ct2d.Params(kappa=30, test_steps=4)
    whole = without_timing(run_experiment(ct2d, params, 5, 3, tmp_path / "whole", batch=3))
    run_experiment(ct2d, params, 5, 3, tmp_path / "part", batch=3)
    for index in (1, 4):  # runs lost from two batches: resumed run by run
        (tmp_path / "part" / "runs" / f"run-{index:06d}.json").unlink()
    resumed = without_timing(run_experiment(ct2d, params, 5, 3, tmp_path / "part", resume=True, batch=2))
    assert json.dumps(resumed, sort_keys=True) == json.dumps(whole, sort_keys=True)


#: fields of a check step that are rounding-level differences of equal numbers (a gap where DMF is
#: exact): two routes round them differently, and the step's verdict (the gap within its bound) is
#: what is compared
ROUNDING_FIELDS = ("gap", "gap_norm", "gap_size", "repaired_gap_norm", "repaired_gap_size", "recursive_gap_norm",
                   "recursive_gap_size", "gap_share", "gap_share_size", "predicted_gap_norm", "unit_dependence")


def _without(record, names):
    if isinstance(record, dict):
        return {k: _without(v, names) for k, v in record.items() if k not in names}
    if isinstance(record, list):
        return [_without(v, names) for v in record]
    return record


#: fields of a check step computed in DMF's own recursion (its estimates and the centre's prediction
#: from them, and the audit's CMF update from that prediction)
DMF_RECURSION = ("dmf_mean", "cmf_mean", "central", "gap_bound")


def _dmf_spread(steps) -> float:
    """The largest relative difference of DMF's and CMF's estimates over a run's steps (both
    recursions, mathematically equal where DMF is exact): the rounding the recursion carries."""
    worst = 0.0
    for e in steps:
        for field in ("means", "covs"):
            dmf, cmf = np.array(e[field]["dmf"]), np.array(e[field]["cmf"])
            worst = max(worst, float(np.max(np.abs(dmf - cmf)) / np.max(np.abs(cmf))))
    return worst


@pytest.mark.slow
@pytest.mark.parametrize("family", ["ukf", "ekf"])
def test_check_batch_equals_the_runs_one_at_a_time(family):
    """check on the three-sensor example (a numpy callable with an angle output among its sensors):
    the same bits for every split of the runs, and as run_one to PER_RUN_RTOL outside DMF's recursion
    and the rounding-level gaps; DMF's recursion within ROUNDING_SPREAD times the run's own DMF −
    CMF spread (as for ct2d), and every step's verdict (the gap within its bound) the same."""
    from gpfverify.experiments import check

    params = check.params_for("examples/three_sensor_system.py:tracker", filter=family, steps=12)
    full = _records(check, params, SEEDS)
    assert _records(check, params, SEEDS[:1]) + _records(check, params, SEEDS[1:4]) + \
        _records(check, params, SEEDS[4:]) == full
    for seed, batch in zip(SEEDS, full):
        alone = untimed(to_json(check.run_one(params, seed)))
        skip = ROUNDING_FIELDS + DMF_RECURSION + ("means", "covs", "nees", "sq_err")
        _assert_close(_without(batch, skip), _without(alone, skip), "check")
        rtol = max(PER_RUN_RTOL, ROUNDING_SPREAD * _dmf_spread(alone["steps"]))
        for got, ref in zip(batch["steps"], alone["steps"]):
            assert (got["gap_size"] <= got["gap_bound"]) == (ref["gap_size"] <= ref["gap_bound"])
            assert abs(got["gap_bound"] - ref["gap_bound"]) <= rtol * ref["gap_bound"]
            for field in ("dmf_mean", "cmf_mean"):
                np.testing.assert_allclose(got[field], ref[field], rtol=0, atol=rtol * np.abs(ref[field]).max())
            for field in ("means", "covs"):
                for method, value in ref[field].items():
                    tol = (rtol if method == "dmf" else PER_RUN_RTOL) * np.abs(value).max()
                    np.testing.assert_allclose(got[field][method], value, rtol=0, atol=tol, err_msg=method)

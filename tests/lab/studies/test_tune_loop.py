"""The hyperparameter search's loop (``baselines/rl_tune.py``): with one trial at a time it is the search Optuna's
own ``study.optimize`` runs (the same values drawn, the same trials pruned at the same points), with more it gives
the same trials in this process and on a cluster, and a killed client's unfinished trials do not block a resume."""

from __future__ import annotations

import math
import sys

import pytest

optuna = pytest.importorskip("optuna")

from ffsr_gym_lab.studies.tune_loop import pruning_judge, search  # noqa: E402
from ffsr_gym_lab.studies.tuning import draw, make_pruner, make_sampler  # noqa: E402

SPACE = {"rate": ("log", 1e-3, 1.0), "width": [1, 2, 3, 4]}
POINTS = 5


def _curve(values: dict, step: int) -> float:
    """A learning curve that rises with the step, and whose height depends on both values (some trials are worse
    than the median at every point, so the pruner has work)."""
    rise = 1.0 - math.exp(-(step + 1) * values["rate"] * 3.0)
    return values["width"] * rise - 0.3 * abs(math.log10(values["rate"]))


def synthetic_piece(values: dict, complete: list) -> dict:
    keep_going, reports, pruned = pruning_judge(complete), [], None
    for step in range(POINTS):
        reports.append([step, _curve(values, step)])
        if not keep_going(step, reports[-1][1]):
            pruned = step
            break
    value = None if pruned is not None else max(v for _, v in reports)
    return {"reports": reports, "pruned_at": pruned, "value": value,
            "env_steps": 100 * len(reports), "wall_time_s": 0.0, "record": {"values": values}}


def _objective(trial) -> float:
    values, best = draw(trial, SPACE), -math.inf
    for step in range(POINTS):
        value = _curve(values, step)
        best = max(best, value)
        trial.report(value, step)
        if trial.should_prune():
            raise optuna.TrialPruned()
    return best


def _study(name: str = "s"):
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.create_study(study_name=name, direction="maximize", sampler=make_sampler(), pruner=make_pruner())


def _trials(study) -> list[tuple]:
    return [(t.number, t.state.name, t.params, t.value, dict(t.intermediate_values)) for t in study.trials]


def test_one_trial_at_a_time_is_the_search_optuna_runs(tmp_path):
    reference = _study()
    reference.optimize(_objective, n_trials=16)
    ours = _study()
    search(ours, synthetic_piece, SPACE, trials=16, batch=1, work=tmp_path, progress=False)
    assert _trials(ours) == _trials(reference)
    states = [t.state.name for t in ours.trials]
    assert states.count("PRUNED") >= 3 and states.count("COMPLETE") >= 6  # the pruner had work, and did it
    assert (tmp_path / "trial15" / "train_record.json").is_file()


def test_a_batch_gives_the_same_trials_here_and_on_a_cluster():
    pytest.importorskip("distributed")
    import cloudpickle

    from ffsr_gym.cluster import cluster_executor

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers do not import the tests
    here = _study()
    search(here, synthetic_piece, SPACE, trials=10, batch=3, progress=False)
    there = _study()
    with cluster_executor("local:2", say=lambda text: None) as (executor, _):
        search(there, synthetic_piece, SPACE, trials=10, batch=3, executor=executor, progress=False)
    assert _trials(there) == _trials(here)
    sequential = _study()
    search(sequential, synthetic_piece, SPACE, trials=10, batch=1, progress=False)
    assert _trials(sequential) != _trials(here)  # a batch is another search: its trials cannot see each other


def test_a_killed_clients_unfinished_trial_is_failed_and_the_search_goes_on():
    study = _study()
    search(study, synthetic_piece, SPACE, trials=3, progress=False)
    study.ask()  # asked, never told: the client died while its piece ran
    search(study, synthetic_piece, SPACE, trials=5, progress=False)
    states = [t.state.name for t in study.trials]
    assert states[3] == "FAIL" and len(states) == 6
    assert sum(s in ("COMPLETE", "PRUNED") for s in states) == 5

"""The theory of a study point computed while it simulates (`study.run._theory_ahead`): the
numbers of the serial computation, and warnings kept to the thread that raised them."""

from __future__ import annotations

import threading
import warnings

import numpy as np

import stickslip as ss
from stickslip.study import measure
from stickslip.study import run as runner

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def study():
    return {
        "model": {"name": "langevin", "params": dict(PUBLIC)},
        "simulation": {"n_paths": 2000, "dt": 0.1, "t_max": 20.0, "seed": 5},
        "analytic": [
            {"method": "truncation", "order": 1},
            {"method": "decoupling", "order": 1},
        ],
        "outputs": ["slip_time", "period", "slip_distance"],
        "grid": {
            "slip_time": {"start": 0, "stop": 12, "bins": 40},
            "period": {"start": 0, "stop": 15, "bins": 30},
            "slip_distance": {"start": -1, "stop": 4, "bins": 25},
        },
    }


def test_theory_ahead_gives_the_serial_numbers(monkeypatch):
    started = []
    ahead = runner._theory_ahead

    def spy(point, s):
        thread = ahead(point, s)
        started.append(thread)
        return thread

    monkeypatch.setattr(runner, "_theory_ahead", spy)
    threaded = ss.run_study(study(), progress=False)
    assert started and started[0] is not None  # (the theory was computed in the thread)
    monkeypatch.setattr(runner, "_theory_ahead", lambda point, s: None)
    serial = ss.run_study(study(), progress=False)
    names = [n for n in serial.variables if not str(n).startswith("seconds_")]
    assert sorted(names) == sorted(
        n for n in threaded.variables if not str(n).startswith("seconds_")
    )
    for name in names:
        a, b = np.asarray(serial[name].values), np.asarray(threaded[name].values)
        assert a.shape == b.shape and a.tobytes() == b.tobytes(), name
    assert serial.attrs["warnings"] == threaded.attrs["warnings"]


def test_open_grid_is_not_computed_ahead():
    from stickslip.study.load import load_study

    s = study()
    s["grid"]["period"] = {"bins": 30}  # (its ends come from the simulated periods)
    loaded = load_study(s)
    point = measure.Point(loaded, {})
    point.exact = object()
    assert runner._theory_ahead(point, loaded) is None


def test_notes_stay_with_the_thread_that_made_them(monkeypatch):
    """A thread collecting notes takes its own; another thread's notes are warnings, shown
    as the filters say; `warnings` itself is left as it was."""
    from stickslip._notes import collecting_notes, note

    shown, caught = [], {}
    inside, done = threading.Event(), threading.Event()
    hook = lambda message, *args, **kwargs: shown.append(str(message))  # noqa: E731
    monkeypatch.setattr(warnings, "filters", [("ignore", None, ResourceWarning, None, 0)])
    monkeypatch.setattr(warnings, "showwarning", hook)
    warnings._filters_mutated()
    filters = list(warnings.filters)

    def theory():
        with collecting_notes() as mine:
            note("note", ss.ApproximationWarning)
            inside.set()
            done.wait(5)
            note("note", ss.ApproximationWarning)  # (again: every one is kept)
        caught["theory"] = [(str(n), n.category) for n in mine]

    thread = threading.Thread(target=theory)
    thread.start()
    inside.wait(5)
    note("simulation", UserWarning)  # (another thread's: shown as before)
    note("hidden", ResourceWarning)  # (ignored, as the filters say)
    done.set()
    thread.join()
    assert caught["theory"] == [("note", ss.ApproximationWarning)] * 2
    assert shown == ["simulation"]
    assert warnings.showwarning is hook and warnings.filters == filters


def test_the_theory_after_the_simulation_gives_the_threaded_numbers_and_notes(monkeypatch):
    """Without the theory thread (`_theory_ahead` starting none), the numbers and notes
    of the threaded run."""
    threaded = ss.run_study(study(), progress=False)
    started = []
    monkeypatch.setattr(runner, "_theory_ahead", lambda p, s: started.append(None))
    plain = ss.run_study(study(), progress=False)
    assert started == [None]
    for name in threaded.variables:
        if not str(name).startswith("seconds_"):
            assert (
                np.asarray(threaded[name].values).tobytes()
                == np.asarray(plain[name].values).tobytes()
            ), name
    assert plain.attrs["warnings"] == threaded.attrs["warnings"]

"""Property-based bad-input tests (Hypothesis): the promise of issue 42, kept.

Whatever a user or a careless script passes, the package answers with one of:
- a `StickSlipError` (a subclass: `ParameterError`, `DataError`, `ResourceError`, ...), whose
  message is one printable line of at most a few hundred characters;
- a result whose numbers are finite where they are defined (nan only where the API documents
  it, e.g. a path not stuck by `t_max`), with a warning where it is doubtful.
From the command line: exit 0, or exit 2 with one line on stderr; the user's files intact.

The default tier runs each property on a few dozen examples, derandomised so that CI sees the
same cases every time (about a minute in all); `pytest -m slow` runs the same properties on
many more examples with a fixed seed.
"""

from __future__ import annotations

import hashlib
import pathlib
import re
import warnings

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import stickslip as ss
from stickslip.cli import main

_COMMON = dict(
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    database=None,
)
FAST = settings(max_examples=60, derandomize=True, **_COMMON)
LONG = settings(max_examples=300, derandomize=True, **_COMMON)

MESSAGE_LIMIT = 400  # characters: "one line of at most a few hundred characters"


@pytest.fixture(autouse=True, scope="module")
def _memory_limit():
    """A case that slipped past the package's own limits must fail in this process with a
    `ResourceError`, not take the machine's memory from the other test workers."""
    mp = pytest.MonkeyPatch()
    mp.setenv("STICKSLIP_MEMORY_LIMIT", "2e9")
    yield
    mp.undo()


def assert_one_line(message: str):
    assert "\n" not in message.strip(), message
    assert len(message) <= MESSAGE_LIMIT, (len(message), message[:200])
    assert message.isprintable(), repr(message[:200])


def both_tiers(strategy, check):
    """`check` over `strategy` at FAST in the default tier and at LONG in the slow tier."""

    @FAST
    @given(strategy)
    def fast(case):
        check(case)

    @pytest.mark.slow
    @LONG
    @given(strategy)
    def slow(case):
        check(case)

    return fast, slow


# -- numbers a user might type ------------------------------------------------------------
awkward_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1.0, 1e20, 1e-20, 1e8, 2.0**53, 5e-324]),
    st.floats(min_value=1e-3, max_value=1e3),
)
awkward_values = st.one_of(
    awkward_floats,
    st.integers(min_value=-(2**70), max_value=2**70),
    st.text(max_size=8),
    st.none(),
    st.booleans(),
    st.lists(st.floats(min_value=0.1, max_value=2.0), max_size=3),
)


def _call(fn, *args, **kwargs):
    """Call fn; a StickSlipError is returned (checked to be one line), warnings collected."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = fn(*args, **kwargs)
        except ss.StickSlipError as err:
            assert_one_line(str(err))
            event(f"{getattr(fn, '__name__', fn)}: {type(err).__name__}")
            return err, caught
    event(f"{getattr(fn, '__name__', fn)}: result")
    return result, caught


_NUMPY_WARNING = re.compile(r"encountered in|divide by zero|empty slice|Degrees of freedom")


def _no_numpy_warnings(caught):
    """NumPy's own floating-point warnings ("overflow encountered in ...") are not messages
    to a user: the package must catch what causes them and say it in its own words."""
    raw = [str(w.message) for w in caught if _NUMPY_WARNING.search(str(w.message))]
    assert not raw, raw


# -- models ---------------------------------------------------------------------------------
LANGEVIN = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


@st.composite
def langevin_params(draw):
    params = dict(LANGEVIN)
    for name in draw(st.sets(st.sampled_from(sorted(LANGEVIN)), min_size=1, max_size=3)):
        params[name] = draw(awkward_values)
    return params


def _model_property(params):
    Model = ss.get_model("langevin")
    model, caught = _call(Model, **params)
    _no_numpy_warnings(caught)
    if isinstance(model, ss.StickSlipError):
        return
    # A model that was built is usable: its scales are finite and a tiny ensemble is finite.
    ens, caught = _call(ss.simulate, model, 64, 0.2, 10.0, seed=1)
    _no_numpy_warnings(caught)
    if isinstance(ens, ss.StickSlipError):
        return
    for q in ("slip_time", "slip_distance", "stick_time"):
        x = np.asarray(getattr(ens, q))
        assert not np.any(np.isinf(x)), q
    stuck = np.isfinite(ens.slip_time)
    assert np.all(np.isfinite(ens.slip_distance[stuck]))
    assert 0.0 <= ens.stats["miss_bound"] <= 1.0


test_langevin_parameters, test_langevin_parameters_long = both_tiers(
    langevin_params(), _model_property
)


# -- simulate's own arguments ---------------------------------------------------------------
@st.composite
def simulate_args(draw):
    """Sensible arguments with one to four of them replaced by awkward values."""
    args = dict(
        n_paths=draw(st.integers(1, 300)),
        dt=draw(st.floats(0.01, 1.0)),
        t_max=draw(st.floats(0.5, 20.0)),
        seed=draw(st.integers(0, 2**31)),
    )
    awkward = dict(
        n_paths=st.one_of(st.integers(-5, 0), st.sampled_from([2**32 - 1, 10**12]), awkward_values),
        dt=awkward_floats,
        t_max=awkward_floats,
        seed=st.one_of(st.integers(-3, -1), st.just(2**70), awkward_values),
    )
    for name in draw(st.sets(st.sampled_from(sorted(args)), max_size=4)):
        args[name] = draw(awkward[name])
    return args


def _simulate_property(args):
    model = ss.get_model("langevin")(**LANGEVIN)
    ens, caught = _call(ss.simulate, model, args["n_paths"], args["dt"], args["t_max"],
                        seed=args["seed"])  # fmt: skip
    _no_numpy_warnings(caught)
    if not isinstance(ens, ss.StickSlipError):
        assert len(ens.slip_time) == args["n_paths"]
        assert not np.any(np.isinf(ens.slip_time))


test_simulate_arguments, test_simulate_arguments_long = both_tiers(
    simulate_args(), _simulate_property
)


# -- extract_cycles ---------------------------------------------------------------------------
@st.composite
def traces(draw):
    n = draw(st.integers(0, 2000))
    kind = draw(st.sampled_from(["noise", "sawtooth", "constant", "junk"]))
    t = np.arange(n) * 0.01
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    if kind == "noise":
        v = 1.0 + rng.standard_normal(n)
    elif kind == "constant":
        v = np.full(n, draw(awkward_floats))
    elif kind == "junk":
        v = rng.standard_normal(n) * draw(st.sampled_from([1e-300, 1e300, 1.0]))
        if n:
            v[rng.integers(0, n, size=max(1, n // 50))] = draw(
                st.sampled_from([np.nan, np.inf, -np.inf, 1e308])
            )
    else:  # a clean stick-slip velocity: sticks at v_b = 1 and slips that dip below
        phase = (t % 2.0) / 2.0
        v = np.where(phase < 0.5, 1.0, 1.0 - np.sin(2 * np.pi * phase) ** 2 * 3.0)
        scale = draw(st.sampled_from([1.0, 1e-300, 1e300]))
        v, v_b = v * scale, scale  # the same trace in other units
    if draw(st.integers(0, 4)) == 0 and n > 3:  # unsorted times, now and then
        t = t.copy()
        t[1], t[2] = t[2], t[1]
    if kind != "sawtooth":
        v_b = 1.0
    if not draw(st.integers(0, 3)):
        v_b = draw(awkward_floats)
    return t, v, v_b


def _extract_property(trace):
    t, v, v_b = trace
    found, caught = _call(ss.extract_cycles, t, v=v, v_b=v_b)
    _no_numpy_warnings(caught)
    if not isinstance(found, ss.StickSlipError):
        for name, column in found.table.items():
            column = np.asarray(column)
            if column.dtype.kind == "f":
                assert np.all(np.isfinite(column)), name


test_extract_cycles_inputs, test_extract_cycles_inputs_long = both_tiers(
    traces(), _extract_property
)


# -- fit's data -------------------------------------------------------------------------------
@st.composite
def degenerate_data(draw):
    n = draw(st.integers(0, 40))
    kind = draw(st.sampled_from(["constant", "few", "2d", "nan", "strings", "negative"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    x = rng.gamma(4.0, 1.0, size=n)
    if kind == "constant":
        x = np.full(max(n, 2), draw(st.floats(0.1, 10.0)))
    elif kind == "few":
        x = x[: draw(st.integers(0, 3))]
    elif kind == "2d":
        x = np.column_stack([x, x])
    elif kind == "nan":
        x = np.append(x, [np.nan, np.inf])
    elif kind == "strings":
        x = [str(v) for v in x] + ["abc"]
    else:
        x = np.append(x, -1.0)
    return {"slip_time": x}


def _fit_property(data):
    fixed = {k: v for k, v in LANGEVIN.items() if k != "D"}
    result, caught = _call(ss.fit, "langevin", data, {"D": (0.05, 2.0)}, fixed, n_sim=2000, seed=3)
    _no_numpy_warnings(caught)
    # every one of these data sets is unusable: the fit must say so before simulating
    assert isinstance(result, ss.StickSlipError), result


test_fit_degenerate_data, test_fit_degenerate_data_long = both_tiers(
    degenerate_data(), _fit_property
)


# -- study files through the command line ------------------------------------------------------
BASE_STUDY = {
    "title": "fuzz",
    "model": {"name": "langevin", "params": dict(LANGEVIN)},
    "simulation": {"n_paths": 200, "dt": 0.2, "t_max": 10, "seed": 0},
    "analytic": [{"method": "truncation", "order": 1}],
    "outputs": ["slip_time"],
    "grid": {"slip_time": {"start": 0, "stop": 10, "bins": 20}},
}
_PATHS = [
    ("model", "name"), ("model", "params", "omega0"), ("model", "params", "D"),
    ("model", "params", "tau"), ("simulation", "n_paths"), ("simulation", "dt"),
    ("simulation", "t_max"), ("simulation", "seed"), ("grid", "slip_time", "bins"),
    ("grid", "slip_time", "stop"), ("outputs",), ("analytic",), ("title",),
]  # fmt: skip


@st.composite
def studies(draw):
    study = yaml.safe_load(yaml.safe_dump(BASE_STUDY))
    for path in draw(st.lists(st.sampled_from(_PATHS), min_size=1, max_size=3, unique=True)):
        node = study
        for key in path[:-1]:
            node = node[key]
        action = draw(st.sampled_from(["value", "typo", "delete"]))
        if action == "value":
            node[path[-1]] = draw(awkward_values)
        elif action == "typo":
            node[path[-1] + draw(st.sampled_from(["_", "s", "X"]))] = node.pop(path[-1])
        else:
            node.pop(path[-1])
    return study


def _snapshot(folder: pathlib.Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _validate_property(tmp_path_factory, study):
    folder = tmp_path_factory.mktemp("study")
    path = folder / "study.yaml"
    try:
        path.write_text(yaml.safe_dump(study, allow_unicode=True), encoding="utf-8")
    except (ValueError, OverflowError):  # a value YAML itself cannot write (nan is fine)
        return
    (folder / "notes.txt").write_text("the user's own notes\n")
    before = _snapshot(folder)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code in (0, 2), (result.exit_code, result.output, result.exception)
    event(f"exit {result.exit_code}")
    if result.exit_code == 2:
        assert_one_line(result.stderr.strip().removeprefix("error: "))
    assert _snapshot(folder) == before


@FAST
@given(studies())
def test_study_validation(tmp_path_factory, study):
    _validate_property(tmp_path_factory, study)


@pytest.mark.slow
@LONG
@given(studies())
def test_study_validation_long(tmp_path_factory, study):
    _validate_property(tmp_path_factory, study)


# -- where results may be written ------------------------------------------------------------
def _out_property(tmp_path_factory, monkeypatch, out, force, command):
    """Whatever --out names, the study, its data and the user's other files stay intact: the
    command refuses (exit 2, one line) or writes its results and touches nothing else."""
    root = tmp_path_factory.mktemp("home")
    work = root / "work"
    (work / "data").mkdir(parents=True)
    (work / "data" / "cycles.csv").write_text("slip_time\n" + "\n".join(
        f"{x:.4f}" for x in np.random.default_rng(0).gamma(4, 1, 50)) + "\n")  # fmt: skip
    study = dict(BASE_STUDY, fit={"data": "data/cycles.csv", "free": {"D": [0.05, 2.0]},
                                  "n_sim": 1000})  # fmt: skip
    (work / "study.yaml").write_text(yaml.safe_dump(study))
    (work / "notes.txt").write_text("notes\n")
    (root / "other").mkdir()
    (root / "other" / "thesis.tex").write_text("\\section{}\n")
    before = _snapshot(root)
    monkeypatch.chdir(work)
    args = [command, "study.yaml", "--out", out, "--quiet"] + (["--force"] if force else [])
    if command == "run":
        args.append("--no-figures")
    result = CliRunner().invoke(main, args)
    assert result.exit_code in (0, 2), (result.output, result.exception)
    event(f"exit {result.exit_code}")
    after = _snapshot(root)
    assert {k: after.get(k) for k in before} == before
    if result.exit_code == 2:
        assert_one_line(result.stderr.strip().removeprefix("error: "))
    else:  # written: a results folder that is no input and holds none, and nothing else
        written = (work / out).resolve()
        inputs = [work / "study.yaml", work / "data" / "cycles.csv", work]
        for path in inputs:  # neither an input nor a folder holding one
            path = path.resolve()
            assert written not in (path, *path.parents)
        assert (written / ".stickslip-results").is_file()
        assert set(after) - set(before) == {
            str(p.relative_to(root)) for p in written.rglob("*") if p.is_file()
        }


_OUTS = ["results", ".", "..", "../..", "study.yaml", "data", "data/sub", "notes.txt",
         "../other", "../results", "", "/", "results/../..", "../other/sub"]  # fmt: skip


_OUT_CASES = (st.sampled_from(_OUTS), st.booleans(), st.sampled_from(["run", "fit"]))


# An allowed --out really runs (a small simulation or fit, about a second): fewer examples.
@settings(max_examples=15, derandomize=True, **_COMMON)
@given(*_OUT_CASES)
def test_outputs_never_touch_inputs(tmp_path_factory, monkeypatch, out, force, command):
    _out_property(tmp_path_factory, monkeypatch, out, force, command)


@pytest.mark.slow
@settings(max_examples=120, derandomize=True, **_COMMON)
@given(*_OUT_CASES)
def test_outputs_never_touch_inputs_long(tmp_path_factory, monkeypatch, out, force, command):
    _out_property(tmp_path_factory, monkeypatch, out, force, command)


# -- user models: shapes and regions of nan ---------------------------------------------------
class _FuzzModel(ss.FrictionModel):
    """An oscillator with friction noise whose methods return the shapes drawn, and whose
    drift is `poison` where x < `below`."""

    drift_shape: tuple = (2,)
    diffusion_shape: tuple = (2, 1)
    onset_shape: tuple = (2,)
    noise: int = 1
    below: float = -10.0
    poison: float = float("nan")

    @property
    def state_names(self):
        return ("x", "v")

    @property
    def noise_dim(self):
        return self.noise

    def drift(self, y):
        import jax.numpy as jnp

        f = jnp.stack([y[1], -y[0] - 0.02 * y[1] ** 3])
        f = jnp.where(y[0] < self.below, self.poison, f)
        return f if self.drift_shape == (2,) else jnp.ones(self.drift_shape) * y[0]

    def diffusion(self, y):
        import jax.numpy as jnp

        return jnp.zeros(self.diffusion_shape).at[..., -1, :].set(0.3) * (y[0] * 0 + 1)

    @property
    def stick_level(self):
        return 1.0

    def onset_state(self, key):
        import jax.numpy as jnp

        return jnp.full(self.onset_shape, 2.0).at[-1:].set(0.0)


user_models = st.builds(
    _FuzzModel,
    drift_shape=st.sampled_from([(2,), (2,), (2,), (3,), (), (2, 1)]),
    diffusion_shape=st.sampled_from([(2, 1), (2, 1), (2, 1), (2,), (2, 2), (1, 1)]),
    onset_shape=st.sampled_from([(2,), (2,), (2,), (3,), (1,)]),
    noise=st.sampled_from([1, 1, 1, 0, 2]),
    below=st.sampled_from([-10.0, -1.8, -1.5, -0.5, 3.0]),
    poison=st.sampled_from([float("nan"), float("inf"), -float("inf"), 1.0]),
)


def _check_user_model(model):
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            ens = ss.simulate(model, 48, 0.02, 12.0, seed=3)
    except ss.StickSlipError as err:
        event(f"refused: {str(err).split(' returns')[0][-30:]}")
        assert_one_line(str(err))
        return
    told = [str(w.message) for w in said if "finite numbers" in str(w.message)]
    n_bad = ens.stats["nonfinite"]
    event(f"ran, {'some' if n_bad else 'no'} non-finite paths")
    assert n_bad == int(ens.nonfinite.sum()) and len(told) == (1 if n_bad else 0), told
    for message in told:
        assert_one_line(message)
    assert not (ens.stuck & ens.nonfinite).any()
    for name in ("slip_time", "stick_time", "period", "slip_distance"):
        values = getattr(ens, name)[ens.stuck]
        assert np.all(np.isfinite(values)), name
    assert np.all(ens.slip_time[ens.stuck & ~ens.immediate] > 0)


test_user_models, test_user_models_long = both_tiers(user_models, _check_user_model)


# -- a damaged compiled-code cache -------------------------------------------------------------
damage = st.lists(
    st.tuples(
        st.sampled_from(["stickslip-exported", "stickslip-executable"]),
        st.sampled_from(["flip", "cut", "swap", "empty"]),
        st.integers(0, 2**20),
        st.integers(1, 255),
    ),
    min_size=1,
    max_size=4,
)


def _damage_once(where: pathlib.Path, case) -> None:
    for folder, kind, at, xor in case:
        files = sorted((where / folder).rglob("*.bin"))
        if not files:
            continue
        file = files[at % len(files)]
        data = bytearray(file.read_bytes())
        if kind == "flip" and data:
            data[at % len(data)] ^= xor
        elif kind == "cut":
            data = data[: at % max(len(data), 1)]
        elif kind == "empty":
            data = bytearray()
        elif kind == "swap":  # another entry's bytes under this name
            data = bytearray(files[(at + 1) % len(files)].read_bytes())
            if len(files) == 1 and data:
                data[len(data) // 2] ^= xor
        file.write_bytes(bytes(data))


def _check_cache_damage(tmp_path_factory, case):
    """Whatever bytes of the cache's entries are changed, cut, emptied or swapped, a new
    call neither crashes nor uses them, and gives the clean cache's numbers to the bit."""
    import jax.numpy as jnp

    from stickslip import _compile
    from stickslip._jax import jax

    where = tmp_path_factory.mktemp("cache")
    before = jax.config.jax_compilation_cache_dir
    x = jnp.linspace(0.0, 1.0, 64)
    fresh = lambda: _compile.eqx.filter_jit(lambda x, y: (jnp.sin(x) * 1.25, {"y": y[0] * 2}))  # noqa: E731
    try:
        jax.config.update("jax_compilation_cache_dir", str(where))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # ("damaged entries ... removed")
            flat = lambda out: np.concatenate([np.ravel(a) for a in jax.tree.leaves(out)])  # noqa: E731
            clean = flat(_compile.call(fresh(), x, (x[:3],), paths=64))
            _damage_once(where, case)
            again = flat(_compile.call(fresh(), x, (x[:3],), paths=64))
            third = flat(_compile.call(fresh(), x, (x[:3],), paths=64))
    finally:
        jax.config.update("jax_compilation_cache_dir", before)
    assert again.tobytes() == clean.tobytes() and third.tobytes() == clean.tobytes()


@settings(max_examples=10, derandomize=True, **_COMMON)
@given(damage)
def test_cache_damage(tmp_path_factory, case):
    _check_cache_damage(tmp_path_factory, case)


@pytest.mark.slow
@settings(max_examples=200, derandomize=True, **_COMMON)
@given(damage)
def test_cache_damage_long(tmp_path_factory, case):
    _check_cache_damage(tmp_path_factory, case)

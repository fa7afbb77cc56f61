"""Plugin discovery through entry points (built by hand: no third-party package needed)."""

import subprocess
import sys
from importlib.metadata import EntryPoint

import pytest

import stickslip
from stickslip import _registry
from stickslip._registry import PluginWarning


def ep(name, value):
    return EntryPoint(name=name, value=value, group=_registry.ENTRY_POINT_GROUP)


def test_builtin_models_are_discovered(Langevin):
    models = stickslip.list_models()
    assert models["langevin"] is Langevin
    assert stickslip.get_model("langevin") is Langevin
    assert stickslip.get_model(Langevin) is Langevin  # a class is accepted as well


def test_unknown_model_names_the_known_ones():
    with pytest.raises(stickslip.PluginError, match=r"unknown model 'nope'.*langevin"):
        stickslip.get_model("nope")


def test_broken_plugin_warns_and_is_skipped():
    with pytest.warns(PluginWarning, match=r"'broken'.*failed to load.*ModuleNotFoundError"):
        models = _registry._load(
            [
                ep("broken", "no_such_module_xyz:Model"),
                ep("langevin", "stickslip_langevin:Langevin"),
            ]
        )
    assert list(models) == ["langevin"]


def test_non_model_plugin_warns():
    with pytest.warns(PluginWarning, match=r"'notamodel'.*not a subclass"):
        models = _registry._load([ep("notamodel", "collections:OrderedDict")])
    assert models == {}


def test_duplicate_plugin_warns():
    with pytest.warns(PluginWarning, match=r"'langevin'.*duplicates"):
        models = _registry._load(
            [
                ep("langevin", "stickslip_langevin:Langevin"),
                ep("langevin", "stickslip_langevin:Langevin"),
            ]
        )
    assert list(models) == ["langevin"]


def test_register_model_at_runtime(Langevin):
    from stickslip import FrictionModel

    class Mine(FrictionModel):  # abstract, but registration only checks the type
        pass

    stickslip.register_model("mine-test", Mine)
    try:
        assert stickslip.get_model("mine-test") is Mine
        with pytest.raises(stickslip.PluginError, match="taken"):
            stickslip.register_model("langevin", Mine)
        with pytest.raises(TypeError):
            stickslip.register_model("bad", dict)
    finally:
        _registry._runtime.pop("mine-test", None)


def test_refresh_rescans(monkeypatch):
    calls = []
    monkeypatch.setattr(_registry, "entry_points", lambda group: calls.append(group) or [])
    _registry.refresh_models()
    try:
        assert stickslip.list_models() == {}
        assert calls == [_registry.ENTRY_POINT_GROUP]
    finally:
        monkeypatch.undo()
        _registry.refresh_models()
    assert "langevin" in stickslip.list_models()


def test_cli_models_lists_langevin():
    out = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "models"], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert "langevin" in out.stdout
    assert "omega0, zeta, D, v_b, x0, tau=None, eta0='zero'" in out.stdout

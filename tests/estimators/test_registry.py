"""Tests of kornia_ilum.estimators.registry: entry-point discovery (real, patched), registration, errors."""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass, field
from types import MappingProxyType, SimpleNamespace
from typing import Any

import pytest
import torch
from kornia_ilum_uniform import UniformEstimator

from kornia_ilum.core.errors import MissingWeightsError, UnknownNameError
from kornia_ilum.estimators import (
    DEFAULT_ESTIMATOR,
    ENTRY_POINT_GROUP,
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    OursEstimator,
    create_estimator,
    estimator_info,
    estimator_registry,
    list_estimators,
    register_estimator,
)
from kornia_ilum.estimators import registry
from kornia_ilum.geometry import mirror_ball_valid


@pytest.fixture(autouse=True)
def clean_registry():
    """Every test starts and ends with a fresh discovery and no runtime registrations."""
    registry._reset()
    yield
    registry._reset()


class ToyEstimator(LightingEstimator):
    """A third-party estimator: constant lighting 2.0, no weights."""

    info = EstimatorInfo("toy", "constant lighting 2", "none: a test double", needs_weights=False)

    def predict(self, crops):
        valid = mirror_ball_valid(32, device=crops.device)
        return LightingEstimate(crops.new_full((len(crops), 3, 32, 32), 2.0) * valid, valid)


class NoInfoEstimator(LightingEstimator):
    def predict(self, crops):  # pragma: no cover - never built
        raise AssertionError


@dataclass
class FakeEntryPoint:
    """What the registry reads from an entry point: name, value, dist.name and load()."""

    name: str
    value: str
    dist_name: str
    target: Any = None
    error: Exception | None = None
    dist: Any = field(init=False)

    def __post_init__(self):
        self.dist = SimpleNamespace(name=self.dist_name)

    def load(self):
        if self.error is not None:
            raise self.error
        return self.target


def real(name: str) -> FakeEntryPoint:
    """The installed entry point ``name``, loaded for real, as a fake with the same fields."""
    (ep,) = [ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP) if ep.name == name]
    return FakeEntryPoint(ep.name, ep.value, ep.dist.name, target=ep.load())


@pytest.fixture
def patch_entry_points(monkeypatch):
    """Replace importlib.metadata.entry_points (what the registry calls) by a list; count the calls."""
    calls = []

    def install(*entry_points: FakeEntryPoint) -> list:
        def fake(*, group):
            calls.append(group)
            return [ep for ep in entry_points] if group == ENTRY_POINT_GROUP else []

        monkeypatch.setattr(importlib.metadata, "entry_points", fake)
        registry._reset()
        return calls

    return install


class TestInstalledEntryPoints:
    """Discovery with the real metadata: `ours` from kornia_ilum itself, `uniform` from the plugin."""

    def test_builtin_and_plugin_discovered(self):
        eps = {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
        assert eps["ours"].value == "kornia_ilum.estimators.ours:OursEstimator"
        assert eps["ours"].dist.name == "kornia_ilum"
        assert eps["uniform"].value == "kornia_ilum_uniform:UniformEstimator"
        assert eps["uniform"].dist.name == "kornia_ilum_uniform"
        assert {"ours", "uniform"} <= set(list_estimators())
        assert estimator_registry()["ours"] is OursEstimator
        assert estimator_registry()["uniform"] is UniformEstimator

    def test_default_estimator_is_the_trained_ours(self):
        assert DEFAULT_ESTIMATOR == "ours"
        info = estimator_info(DEFAULT_ESTIMATOR)
        assert len(info.weights) == 1 and info.needs_weights and info.pretrained_available
        est = create_estimator(DEFAULT_ESTIMATOR)  # pretrained=True
        assert isinstance(est, OursEstimator) and not est.training
        assert len(est(torch.full((2, 3, 256, 256), 0.5))) == 2
        uniform = create_estimator("uniform")  # the baseline needs no weights
        assert type(uniform).__name__ == "UniformEstimator" and not estimator_info("uniform").needs_weights

    def test_estimator_without_weights(self, untrained_name):
        with pytest.raises(
            MissingWeightsError,
            match=r"^'untrained' is registered but ships no trained weights yet; pass pretrained=False for an "
            r"untrained model or pick one of: ours, sh, sipr, uniform$",
        ):
            create_estimator(untrained_name)
        net = create_estimator("ours", pretrained=False)
        assert isinstance(net, OursEstimator)
        assert create_estimator("ours", pretrained=False, latent_dim=8).latent_dim == 8

    def test_estimator_info(self):
        ours, uniform = estimator_info("ours"), estimator_info("uniform")
        assert "LeGendre" in ours.paper and "Learning Illumination from Diverse Portraits" in ours.paper
        assert ours.input_size == uniform.input_size == 256
        assert len(ours.weights) == 1 and ours.needs_weights and ours.pretrained_available
        assert uniform.paper.startswith("none") and uniform.description

    def test_unknown_name_lists_valid_names(self):
        with pytest.raises(UnknownNameError, match=r"unknown estimator 'nope'\. Valid names: ours, sh, sipr, uniform; "
                           r"an estimator plugin registers its estimators in the entry-point group "):
            create_estimator("nope")
        with pytest.raises(ValueError, match="Valid names: ours, sh, sipr, uniform"):
            estimator_info("nope")

    def test_list_pattern(self):
        assert list_estimators() == sorted(list_estimators())
        assert list_estimators("u*") == ["uniform"]
        assert list_estimators("*rs") == ["ours"]
        assert list_estimators("zz*") == []
        assert list_estimators("Ours") == []  # case-sensitive


class TestPatchedEntryPoints:
    """fsspec style: importlib.metadata.entry_points is patched, nothing is installed."""

    def test_third_party_plugin_discovered(self, patch_entry_points):
        calls = patch_entry_points(
            real("ours"), FakeEntryPoint("toy", "toy_pkg:ToyEstimator", "toy-pkg", target=ToyEstimator)
        )
        assert calls == []  # lazy: nothing is read before the registry is used
        assert list_estimators() == ["ours", "toy"]
        est = create_estimator("toy")(torch.rand(1, 3, 256, 256))
        assert est.mirror_ball.amax().item() == 2.0
        assert estimator_info("toy").name == "toy"
        list_estimators()
        estimator_registry()
        assert calls == [ENTRY_POINT_GROUP]  # read once, then cached

    def test_broken_plugin_warns_and_others_load(self, patch_entry_points):
        patch_entry_points(
            FakeEntryPoint(
                "broken", "broken_pkg.mod:Est", "broken-dist", error=ImportError("No module named 'scipyx'")
            ),
            FakeEntryPoint("toy", "toy_pkg:ToyEstimator", "toy-pkg", target=ToyEstimator),
            real("ours"),
        )
        with pytest.warns(RuntimeWarning) as record:
            names = list_estimators()
        assert names == ["ours", "toy"]
        (message,) = [str(w.message) for w in record]
        assert "'broken = broken_pkg.mod:Est'" in message and "'broken-dist'" in message
        assert "ImportError: No module named 'scipyx'" in message
        with pytest.raises(ValueError, match="unknown estimator 'broken'"):
            create_estimator("broken")

    @pytest.mark.parametrize(
        ("target", "reason"),
        [
            (torch.nn.Linear, "not a subclass of kornia_ilum.estimators.LightingEstimator"),
            (len, "not a subclass"),
            (NoInfoEstimator, "has no class attribute info of type EstimatorInfo"),
        ],
        ids=["module", "function", "no_info"],
    )
    def test_wrong_type_warns(self, patch_entry_points, target, reason):
        patch_entry_points(FakeEntryPoint("bad", "bad_pkg:Thing", "bad-dist", target=target), real("ours"))
        with pytest.warns(
            RuntimeWarning,
            match=f"skipping estimator plugin entry point 'bad = bad_pkg:Thing'.*"
            f"'bad-dist'.*TypeError.*{reason}",
        ):
            assert list_estimators() == ["ours"]

    def test_duplicate_name_from_two_distributions(self, patch_entry_points):
        patch_entry_points(
            FakeEntryPoint("toy", "toy_pkg:ToyEstimator", "toy-pkg", target=ToyEstimator),
            FakeEntryPoint("toy", "other_pkg:Other", "other-pkg", target=OursEstimator),
        )
        with pytest.warns(
            RuntimeWarning,
            match=r"estimator name 'toy' is declared twice: by entry point 'toy = other_pkg:Other'.*"
            r"'other-pkg'.*"
            r"'toy_pkg:ToyEstimator' of distribution 'toy-pkg'; keeping the latter",
        ):
            assert list_estimators() == ["toy"]
        assert estimator_registry()["toy"] is ToyEstimator  # the first found on sys.path wins

    def test_same_entry_point_twice_is_silent(self, patch_entry_points, recwarn):
        ep = FakeEntryPoint("toy", "toy_pkg:ToyEstimator", "toy-pkg", target=ToyEstimator)
        patch_entry_points(ep, ep)
        assert list_estimators() == ["toy"]
        assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]

    def test_plugin_not_installed(self, patch_entry_points):
        """The registry names no plugin by hand: it says where estimators come from (a ValueError, typed)."""
        patch_entry_points(real("ours"))
        with pytest.raises(
            UnknownNameError,
            match=r"unknown estimator 'uniform'\. Valid names: ours; .*'kornia_ilum\.estimators'.*pip install "
            r"\./plugins/NAME",
        ):
            create_estimator("uniform")
        assert issubclass(UnknownNameError, ValueError)
        assert isinstance(create_estimator(DEFAULT_ESTIMATOR), OursEstimator)  # ships in kornia_ilum itself

    def test_no_plugins(self, patch_entry_points):
        patch_entry_points()
        assert list_estimators() == [] and dict(estimator_registry()) == {}
        with pytest.raises(ValueError, match="Valid names: none"):
            create_estimator("ours")


class TestRegisterEstimator:
    def test_register_class(self):
        register_estimator("toy", ToyEstimator)
        assert "toy" in list_estimators() and estimator_registry()["toy"] is ToyEstimator
        assert create_estimator("toy", pretrained=False)(torch.rand(1, 3, 256, 256)).mirror_ball.amax() == 2.0

    def test_clobber(self):
        register_estimator("toy", ToyEstimator)
        with pytest.raises(
            ValueError, match=r"estimator 'toy' is already registered \(ToyEstimator\); pass clobber=True"
        ):
            register_estimator("toy", OursEstimator)
        assert estimator_registry()["toy"] is ToyEstimator
        register_estimator("toy", OursEstimator, clobber=True)
        assert estimator_registry()["toy"] is OursEstimator

    def test_clobber_entry_point(self):
        with pytest.raises(ValueError, match=r"estimator 'ours' is already registered \(OursEstimator\)"):
            register_estimator("ours", ToyEstimator)
        register_estimator("ours", ToyEstimator, clobber=True)  # runtime registrations win
        assert estimator_registry()["ours"] is ToyEstimator
        registry._reset()
        assert estimator_registry()["ours"] is OursEstimator

    def test_string_target_is_lazy(self):
        register_estimator("later", "no_such_module_xyz:Estimator")  # not imported yet
        assert "later" in list_estimators()
        with pytest.raises(ModuleNotFoundError, match="no_such_module_xyz"):
            create_estimator("later")
        register_estimator("ours2", "kornia_ilum.estimators.ours:OursEstimator")
        assert isinstance(create_estimator("ours2", pretrained=False), OursEstimator)

    def test_string_target_resolution_checks_type(self):
        register_estimator("linear", "torch.nn:Linear")
        with pytest.raises(
            TypeError, match=r"estimator 'linear' registered as 'torch.nn:Linear'.*not a subclass"
        ):
            create_estimator("linear")

    def test_bad_targets(self):
        with pytest.raises(TypeError, match="target for estimator 'x' is .* not a subclass"):
            register_estimator("x", torch.nn.Linear)
        with pytest.raises(TypeError, match="has no class attribute info"):
            register_estimator("x", NoInfoEstimator)
        with pytest.raises(
            ValueError, match=r"target must be a class or a 'module:attr' string, got 'nocolon'"
        ):
            register_estimator("x", "nocolon")
        with pytest.raises(ValueError, match="name must be a non-empty string"):
            register_estimator("", ToyEstimator)
        assert "x" not in list_estimators()


class TestRegistryView:
    def test_read_only(self):
        view = estimator_registry()
        assert isinstance(view, MappingProxyType)
        with pytest.raises(TypeError, match="does not support item assignment"):
            view["toy"] = ToyEstimator  # type: ignore[index]
        with pytest.raises(TypeError):
            del view["ours"]  # type: ignore[attr-defined]

    def test_live(self):
        view = estimator_registry()
        assert "toy" not in view
        register_estimator("toy", ToyEstimator)
        assert view["toy"] is ToyEstimator

    def test_pending_strings_resolved(self):
        register_estimator("ours2", "kornia_ilum.estimators.ours:OursEstimator")
        assert estimator_registry()["ours2"] is OursEstimator
        register_estimator("bad", "no_such_module_xyz:Estimator")
        with pytest.raises(ModuleNotFoundError):
            estimator_registry()

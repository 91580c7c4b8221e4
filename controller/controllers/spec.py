"""The controller specification: which controller, with which settings and sets.

One typed definition of what a controller needs, validated in one place. The server
builds a `ControllerSpec` for every route that takes settings (worker controller, trial
start, what-if) and answers 422 naming the field when it cannot. It crosses the worker
pipe as it is (a frozen dataclass pickles); the worker runs its checks again before
building (unpickling does not) and refuses anything that does not validate. Stored run
snapshots and JSON requests use the plain mapping `to_config()` gives:

    {"settings": {...ControllerConfig fields...},
     "models": {...ModelSet JSON...} or "models_path": "models.json",      # UMC, E-UMC
     "utilities": {...UtilitySet JSON...} or "utilities_path": "utilities.json",
     "priors": {...LearnedPriors JSON...}}                                  # optional

Priors are one typed definition, `LearnedPriors` (values, estimate, provenance). Without
one the settings' `priors` apply (equal by default, the paper's controller bit for bit);
with one, its values become the settings' priors, and a settings mapping that asks for
other priors at the same time is refused. Whatever the source, the UMC refuses priors
outside the safe set of its utility table (`controller.intent.prior_safety`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from controller.config import ControllerConfig, SettingError
from controller.controllers import registry
from controller.intent.learned_priors import LearnedPriors
from controller.intent.posteriors import EQUAL_PRIORS

_KEYS = frozenset({"settings", "models", "models_path", "utilities", "utilities_path",
                   "priors"})


@dataclass(frozen=True)
class ControllerSpec:
    """A controller by name, its validated settings, and references to its sets.

    A set is given inline (`models`, a JSON document) or by file (`models_path`); the
    UMC and E-UMC need both sets, the PEC and `none` none. Construction validates, so
    an instance is a configuration that may be sent to the worker.
    """

    name: str
    settings: ControllerConfig = field(default_factory=ControllerConfig)
    models: Mapping[str, Any] | None = None
    models_path: str | None = None
    utilities: Mapping[str, Any] | None = None
    utilities_path: str | None = None
    priors: LearnedPriors | None = None

    def __post_init__(self) -> None:
        reg = registry.lookup(self.name)
        if reg is None:
            raise SettingError("name", f"unknown controller {self.name!r}; choose one of "
                               f"{', '.join(registry.names())}")
        if not isinstance(self.settings, ControllerConfig):
            raise SettingError("settings", "must be a ControllerConfig")
        for key in ("models", "utilities"):
            inline, path = getattr(self, key), getattr(self, f"{key}_path")
            if inline is not None and not isinstance(inline, Mapping):
                raise SettingError(key, f"must be a JSON object, got {type(inline).__name__}")
            if path is not None and not isinstance(path, str):
                raise SettingError(f"{key}_path", f"must be a path, got {path!r}")
            if reg.needs_models and inline is None and not path:
                raise SettingError(key, f"controller {self.name} needs '{key}' or "
                                   f"'{key}_path'")
        if self.priors is not None:
            if not isinstance(self.priors, LearnedPriors):
                raise SettingError("priors", "must be a LearnedPriors record")
            v = self.priors.values
            values = (v[0], v[1], v[2], v[3])
            asked = tuple(self.settings.priors)
            if asked != values and asked != tuple(EQUAL_PRIORS):
                raise SettingError("priors", f"settings ask for priors {list(asked)} but the "
                                   f"priors record {self.priors.version!r} holds "
                                   f"{list(values)}; give one or the other")
            if asked != values:
                object.__setattr__(self, "settings",
                                   dataclasses.replace(self.settings, priors=values))

    @classmethod
    def from_config(cls, name: str, config: Mapping[str, Any] | None = None) -> ControllerSpec:
        """Validate a wire mapping (see the module docstring); unknown keys are refused."""
        cfg = {} if config is None else config
        if not isinstance(cfg, Mapping):
            raise SettingError("config", f"must be a mapping, got {type(cfg).__name__}")
        unknown = sorted(set(cfg) - _KEYS)
        if unknown:
            raise SettingError(unknown[0], f"unknown configuration key(s) "
                               f"{', '.join(unknown)}; expected {', '.join(sorted(_KEYS))}")
        raw = cfg.get("settings", {})
        if isinstance(raw, ControllerConfig):
            settings = raw
        elif isinstance(raw, Mapping):
            settings = ControllerConfig.from_json(dict(raw))
        else:
            raise SettingError("settings", "must be a mapping of controller parameters")
        paths = {k: cfg.get(k) for k in ("models_path", "utilities_path")}
        raw_priors = cfg.get("priors")
        priors = None
        if isinstance(raw_priors, LearnedPriors):
            priors = raw_priors
        elif raw_priors is not None:
            try:
                priors = LearnedPriors.from_json(raw_priors)
            except ValueError as exc:
                raise SettingError("priors", str(exc)) from None
        return cls(name, settings, cfg.get("models"),
                   None if paths["models_path"] is None else str(paths["models_path"]),
                   cfg.get("utilities"),
                   None if paths["utilities_path"] is None else str(paths["utilities_path"]),
                   priors)

    def to_config(self) -> dict[str, Any]:
        """The wire mapping: JSON-able, and `from_config` gives this spec back."""
        out: dict[str, Any] = {"settings": self.settings.to_json()}
        for key in ("models", "models_path", "utilities", "utilities_path"):
            v = getattr(self, key)
            if v is not None:
                out[key] = dict(v) if isinstance(v, Mapping) else v
        if self.priors is not None:
            out["priors"] = self.priors.to_json()
        return out

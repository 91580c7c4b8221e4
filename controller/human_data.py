"""Reference human motion data: mean hip angle and hip extension torque over progress.

The utilities are computed from it (paper, "Calculating Utilities"). One container for
any source: the simulated wearer's built-in dataset, or a lab's own measurements
imported from CSV. Stored as versioned JSON together with where it came from.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

HUMAN_MOTIONS: tuple[str, str, str, str] = ("squat", "stoop_left", "stoop_right", "walking")
LEGS: tuple[str, str] = ("left", "right")
N_PROGRESS = 101
FORMAT_VERSION = 1


@dataclass(frozen=True)
class HumanMotionData:
    """Hip flexion `theta` (rad) and hip extension torque `tau` (Nm, extension positive,
    per leg) for every motion and leg over progress `s_n = n / 100`.

    Arrays have shape (4 motions, 2 legs, 101) in `HUMAN_MOTIONS` and `LEGS` order.
    Walking is one gait cycle starting at heel strike of the left leg.
    """

    theta: NDArray[np.float64]
    tau: NDArray[np.float64]
    source: str = "unspecified"
    version: str = "1"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        shape = (len(HUMAN_MOTIONS), len(LEGS), N_PROGRESS)
        for name in ("theta", "tau"):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.shape != shape:
                raise ValueError(f"human data {name}: expected shape {shape}, got {arr.shape}")
            if not np.isfinite(arr).all():
                bad = np.argwhere(~np.isfinite(arr))[0]
                raise ValueError(
                    f"human data {name}: non-finite value at motion {HUMAN_MOTIONS[bad[0]]}, "
                    f"leg {LEGS[bad[1]]}, n={bad[2]}"
                )
            object.__setattr__(self, name, arr)

    def angle(self, motion: str, leg: str) -> NDArray[np.float64]:
        """theta over progress for one motion and leg."""
        return self.theta[HUMAN_MOTIONS.index(motion), LEGS.index(leg)]

    def torque(self, motion: str, leg: str) -> NDArray[np.float64]:
        """tau over progress for one motion and leg."""
        return self.tau[HUMAN_MOTIONS.index(motion), LEGS.index(leg)]

    def to_json(self) -> dict[str, Any]:
        """Plain JSON-able dictionary (format versioned)."""
        return {
            "format": "exostudy.human_motion_data",
            "format_version": FORMAT_VERSION,
            "source": self.source,
            "version": self.version,
            "meta": self.meta,
            "motions": {
                m: {
                    leg: {
                        "theta_rad": self.theta[i, j].tolist(),
                        "tau_nm": self.tau[i, j].tolist(),
                    }
                    for j, leg in enumerate(LEGS)
                }
                for i, m in enumerate(HUMAN_MOTIONS)
            },
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> HumanMotionData:
        """Inverse of `to_json`, with errors that name the missing part."""
        if data.get("format") != "exostudy.human_motion_data":
            raise ValueError("not an exostudy.human_motion_data document")
        if data.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported format_version {data.get('format_version')!r}")
        motions = data.get("motions", {})
        theta = np.zeros((len(HUMAN_MOTIONS), len(LEGS), N_PROGRESS))
        tau = np.zeros_like(theta)
        for i, m in enumerate(HUMAN_MOTIONS):
            for j, leg in enumerate(LEGS):
                try:
                    entry = motions[m][leg]
                    theta[i, j] = entry["theta_rad"]
                    tau[i, j] = entry["tau_nm"]
                except KeyError as exc:
                    raise ValueError(
                        f"human data: missing {exc} for motion {m}, leg {leg}"
                    ) from exc
                except ValueError as exc:
                    raise ValueError(f"human data: motion {m}, leg {leg}: {exc}") from exc
        return cls(
            theta=theta,
            tau=tau,
            source=str(data.get("source", "unspecified")),
            version=str(data.get("version", "1")),
            meta=dict(data.get("meta", {})),
        )

    def save(self, path: Path) -> None:
        """Write as JSON."""
        path.write_text(json.dumps(self.to_json(), indent=1))

    @classmethod
    def load(cls, path: Path) -> HumanMotionData:
        """Read a file written by `save`."""
        return cls.from_json(json.loads(path.read_text()))

"""The two baseline conditions of a muscle-activity study, as plan entries.

Why: a study reports how much a controller lowers muscle activity, which needs a
reference measured on the same wearer, counterbalanced and blinded like the
controllers: the exoskeleton worn with its springs never locked (what the device's mass
and straps cost), and no exoskeleton at all (the wearer's own activity). Both never
lock, so they reuse the recording controller; they differ in what they declare:
"no exoskeleton" is not worn, so a simulation gives the wearer no torque and a lab takes
its lifts from the experimenter's markers.
"""

from __future__ import annotations

from controller.controllers.passthrough import PassThroughController
from controller.controllers.registry import PlanPlace, register
from controller.controllers.spec import ControllerSpec

#: Names stored with trials and used by the results (never change them).
SPRINGS_FREE = "springs_free"
NO_EXOSKELETON = "no_exoskeleton"


@register(SPRINGS_FREE, label="springs free", colour="#7f7f7f", marker="x",
          plan=PlanPlace(rank=20, counterbalanced=True, baseline=True))
def build_springs_free(spec: ControllerSpec) -> PassThroughController:
    """The exoskeleton worn, its springs never locked."""
    return PassThroughController(spec.settings.layout)


@register(NO_EXOSKELETON, label="no exoskeleton", colour="#bcbd22", marker="+",
          plan=PlanPlace(rank=21, counterbalanced=True, baseline=True),
          exoskeleton_worn=False)
def build_no_exoskeleton(spec: ControllerSpec) -> PassThroughController:
    """No exoskeleton worn: nothing to lock (a simulation gives no torque)."""
    return PassThroughController(spec.settings.layout)

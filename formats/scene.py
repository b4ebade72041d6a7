"""How an animation sits in its scene: units, up axis, first frame and the mesh's prim path.

A capture comes from a pipeline with its own conventions (a Houdini or Maya export in
centimetres, Z up, at time codes 1001…, the mesh at ``/World/body``). skinsynth computes in the
input's own numbers and never converts them; it carries these four facts from the input through
every stage file (as attributes of ``/examples``) and states them again in every USD it writes,
so a DCC shows the result at the input's size, orientation and frames.

Inputs without them (npz, h5, frame files) get the defaults below, which ``fit-skin`` prints and
lets the user override (``--meters-per-unit``, ``--up-axis``, ``--start-frame``).
"""

from dataclasses import dataclass, replace

import numpy as np

UP_AXES = ("Y", "Z")


@dataclass(frozen=True)
class Scene:
    """meters_per_unit (USD ``metersPerUnit``); up_axis "Y" or "Z"; start_frame, the time code of
    frame 0; prim_path, the mesh's absolute USD path (written again by single-mesh USD outputs)."""

    meters_per_unit: float = 1.0
    up_axis: str = "Y"
    start_frame: float = 0.0
    prim_path: str = "/mesh"

    def attributes(self):
        """The ``/examples`` attributes that store it."""
        return {"@meters_per_unit": float(self.meters_per_unit), "@up_axis": self.up_axis,
                "@start_frame": float(self.start_frame), "@prim_path": self.prim_path}

    @classmethod
    def from_attributes(cls, group):
        """From a read ``/examples`` group (files from before it was stored: the defaults)."""
        default = cls()
        return cls(meters_per_unit=float(group.get("@meters_per_unit", default.meters_per_unit)),
                   up_axis=str(group.get("@up_axis", default.up_axis)),
                   start_frame=float(group.get("@start_frame", default.start_frame)),
                   prim_path=str(group.get("@prim_path", default.prim_path)))

    def overridden(self, meters_per_unit=None, up_axis=None, start_frame=None):
        """A copy with the user's options (None: keep) applied; ValueError for bad values."""
        changes = {}
        if meters_per_unit is not None:
            if not (np.isfinite(meters_per_unit) and meters_per_unit > 0.0):
                raise ValueError(f"--meters-per-unit must be a positive number (got {meters_per_unit})")
            changes["meters_per_unit"] = float(meters_per_unit)
        if up_axis is not None:
            if up_axis not in UP_AXES:
                raise ValueError(f"--up-axis must be one of {', '.join(UP_AXES)} (got {up_axis})")
            changes["up_axis"] = up_axis
        if start_frame is not None:
            if not np.isfinite(start_frame):
                raise ValueError(f"--start-frame must be a finite number (got {start_frame})")
            changes["start_frame"] = float(start_frame)
        return replace(self, **changes)

    @property
    def prim_name(self):
        return self.prim_path.rsplit("/", 1)[-1]

    def describe(self, frames):
        """One phrase for a summary: '0.01 m per unit, Z up, frames 1001–1048, /World/body'."""
        last = self.start_frame + frames - 1
        return (f"{self.meters_per_unit:g} m per unit, {self.up_axis} up, frames {self.start_frame:g}–{last:g}, "
                f"{self.prim_path}")

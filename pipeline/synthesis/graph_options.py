"""build-graph's options and their defaults, stated once (no heavy import: the CLI reads its
option defaults from here)."""

import dataclasses
from dataclasses import dataclass


@dataclass(frozen=True)
class GraphOptions:
    """build-graph's options, each default stated here once (the CLI's defaults, :func:`build_graph`'s,
    and what synthesize assumes for a file that does not record one): threshold_scale and
    threshold_reference (T_c, :func:`.transitions.find_transitions`), edge_threshold, min_bones and
    single_component (:mod:`.bone_graph`), svd_threshold (eq. 3–4), min_gap, min_segment (frames;
    the CLI's default is half a second, :func:`.motion_graph.default_min_segment`), coverage,
    up_axis (0, 1, 2) and posture_weight (:func:`.transitions.posture_costs`); contacts (look for the
    input's ground contacts) and their thresholds contact_height (share of the height above the
    ground), contact_speed (share of the height per second), contact_release (the factor beyond
    which a contact is left), contact_min_duration (seconds) and contact_min_support (the least share
    of the frames the ground must bear the body in) (:func:`.contact_patches.find_contacts`)."""

    threshold_scale: float = 3.0
    threshold_reference: str = "median-step"
    edge_threshold: float = 0.1
    single_component: bool = False
    svd_threshold: float = 0.005
    min_gap: int = 2
    min_bones: int = 3
    min_segment: int = 12
    coverage: float = 0.95
    up_axis: int = 1
    posture_weight: float = 1.0
    contacts: bool = True
    contact_height: float = 0.02
    contact_speed: float = 1.0
    contact_release: float = 1.5
    contact_min_duration: float = 0.1
    contact_min_support: float = 0.12

    def analysis_options(self):
        """{name: value} of the options :func:`.graph.build_graph` takes: all but the contacts'
        (found apart from the analysis, by :func:`.contact_patches.find_contacts`)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if not f.name.startswith("contact")}

    def parameters(self, walk_clips):
        """{name: value} of the options as build-graph's provenance records them: ``up_axis`` as
        "X", "Y" or "Z", ``clips`` the names of the clips walks may play (``walk_clips``)."""
        return dict(threshold_scale=self.threshold_scale, threshold_reference=self.threshold_reference,
                    edge_threshold=self.edge_threshold, single_component=self.single_component,
                    svd_threshold=self.svd_threshold, min_gap=self.min_gap, min_segment=self.min_segment,
                    coverage=self.coverage, up_axis="XYZ"[self.up_axis], posture_weight=self.posture_weight,
                    clips=list(walk_clips), contacts=self.contacts, contact_height=self.contact_height,
                    contact_speed=self.contact_speed, contact_release=self.contact_release,
                    contact_min_duration=self.contact_min_duration, contact_min_support=self.contact_min_support)

    @classmethod
    def recorded(cls, values):
        """The options a graph file records ({name: value}, ``up_axis`` as "X", "Y" or "Z"), with
        these defaults for any it does not."""
        fields = {f.name: f for f in dataclasses.fields(cls)}
        known = {name: value for name, value in values.items() if name in fields and name != "up_axis"}
        options = {name: type(fields[name].default)(value) for name, value in known.items()}
        return cls(**options, up_axis="XYZ".index(str(values.get("up_axis", "Y"))))

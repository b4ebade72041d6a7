"""The page ``skinsynth view`` serves: a viser server, its scene, its panel and what each control
does. Interaction glue only: what the colours and distances mean is ``pipeline.view.scenes``,
reading and writing files is ``cli/view.py``'s (through ``formats``), which fills in a plain
record and hands it to :func:`serve`.

One page per kind of file, each from its record (:mod:`.records`):

- a puppet (:class:`PuppetView`, with a :class:`TrajectoryView` it plays): :mod:`.puppet_page`;
- a skin fit (:class:`SkinView`): :mod:`.skin_page`;
- a synthesis (:class:`SynthesisView`): :mod:`.synthesis_page`;
- any animated meshes (:class:`SequenceView`): :mod:`.sequence_page`;

the skin's and the synthesis's records built from a fit's arrays (:mod:`.views`), the frame
slider they share (:mod:`.timeline`), the first view's framing (:mod:`.framing`)
and the server (:mod:`.server`: :func:`serve`, :func:`open_page`, :func:`check_port`). Meshes
are one colour each in viser, so a coloured mesh is sent as one part per colour
(``scenes.split_by_key``). viser is imported when a server starts: importing this package, or any
of its modules, does not import it.

Public: serve, open_page, check_port, PAGES, TrajectoryView, PuppetView, SkinView, SynthesisView,
SequenceView, Timeline, PuppetPage, SkinPage, SynthesisPage, SequencePage, skin_view, synthesis_view,
skeleton_at.
"""

from ..._lazy import lazy_exports

_EXPORTS = {"serve": "server", "open_page": "server", "check_port": "server", "PAGES": "server",
            "TrajectoryView": "records", "PuppetView": "records", "SkinView": "records", "SynthesisView": "records",
            "SequenceView": "records", "Timeline": "timeline", "PuppetPage": "puppet_page", "SkinPage": "skin_page",
            "SynthesisPage": "synthesis_page", "SequencePage": "sequence_page", "skin_view": "views",
            "synthesis_view": "views", "skeleton_at": "views"}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

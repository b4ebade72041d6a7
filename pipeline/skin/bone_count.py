"""How many bones a clip needs (``fit-skin --bones auto``, issue 68): the elbow of its error curve.

Dem Bones' users choose the bone count by hand from the error against bones: more bones always fit
better, but past the count of the parts that truly move apart each one buys less. That curve is
measured cheaply here with rigid clusters (every vertex on one bone, no blending: the clustering a
skinning fit starts from, :mod:`.skin_init`), grown one bone at a time: from one cluster, the
cluster that explains its vertices worst is split (the quarter of it nearest its worst vertex in the
rest pose) and every vertex relabelled to the cluster whose rigid motion reproduces it best; the
RMS error over the rest diagonal is recorded at each count up to ``max_bones``
(:data:`AUTO_MAX_BONES`). Deterministic: no random choice.

**The rule**: the count at the curve's elbow, the point of the log-error curve farthest below the
chord from its first count to its last (both axes scaled to [0, 1]: the "kneedle" of Satopää et al.
2011). On a log scale a fixed *share* of error saved per bone is a straight line, so the elbow is
where the share each bone saves falls most sharply, and a constant factor (the units) moves no
point: the walker (ten rigid parts, soft knees) gives 10, at 48 fps, Z up in centimetres, with a
still first second and mirrored alike; the generated humanoid (17 bones, its neck and hands a few
centimetres long) 16. A clip that one rigid motion reproduces (error under :data:`EXACT` of the
diagonal at one bone) gets 1. Captures have no sharp elbow (their error falls smoothly, soft tissue
and cloth everywhere): the elbow then gives the count past which bones buy detail rather than parts
(the samba 14, the dancer 12, the gallop 13): a rig to start from; docs/own_capture.md and the
summary say to choose more for a finer fit.
"""

from dataclasses import dataclass

import numpy as np

#: The largest count tried: the curve's chord ends there, so the elbow is the same for any clip
#: whose parts are well under it (48: twice the counts the shared captures are fitted with).
AUTO_MAX_BONES = 48
#: An error (RMS over the rest diagonal) this small at one bone: one rigid motion is the clip.
EXACT = 1e-6
#: How the count is chosen, said in the summary.
RULE = "the elbow of the rigid-cluster error curve (1 to {} bones)"


@dataclass
class BoneCount:
    """The count chosen and the curve it was read from: count; counts (K,) int and errors (K,)
    the RMS error of that many rigid clusters over the rest diagonal; rule (str)."""

    count: int
    counts: np.ndarray
    errors: np.ndarray
    rule: str

    def near(self, spread=2):
        """[(count, error)] of the counts within ``spread`` of the one chosen: the curve around it."""
        keep = np.abs(self.counts - self.count) <= spread
        return [(int(k), float(e)) for k, e in zip(self.counts[keep], self.errors[keep])]


def rigid_cluster_errors(vertices, rest, max_bones, diagonal):
    """(counts (K,), errors (K,)): the RMS error over ``diagonal`` of 1, 2, … ``max_bones`` rigid
    clusters of the examples vertices (F, V, 3) from ``rest`` (V, 3), each grown from the last by
    one split and one relabelling (module notes). A relabelling that empties a cluster gives that
    count again; the lowest error of each count is kept."""
    from .bone_transforms import Trajectories, fit_cluster_transforms, single_bone_errors
    from .skin_init import relabel, split_off

    data = Trajectories(vertices, rest)
    frames, count = data.frames, data.count
    rest = np.asarray(rest, dtype=np.float64)
    labels = np.zeros(count, dtype=np.int64)
    clusters, found = 1, {}
    for _ in range(2 * max_bones):  # a split that relabelling undoes is tried again on the next worst
        labels, clusters = relabel(labels, clusters, data)
        own = single_bone_errors(fit_cluster_transforms(labels, clusters, data), data)[np.arange(count), labels]
        rms = float(np.sqrt(own.sum() / (count * frames))) / diagonal
        found[clusters] = min(found.get(clusters, np.inf), rms)
        if clusters >= min(max_bones, count):
            break
        per = np.bincount(labels, weights=own, minlength=clusters)
        per[np.bincount(labels, minlength=clusters) < 2] = -1.0
        members = np.flatnonzero(labels == int(np.argmax(per)))
        split_off(labels, members, members[np.argmax(own[members])], clusters, rest)
        clusters += 1
    counts = np.array(sorted(found))
    return counts, np.array([found[k] for k in counts])


def elbow(counts, errors):
    """The count at the elbow of the log-error curve (module notes): farthest below the chord from
    the first point to the last, both axes scaled to [0, 1]; ties to the fewer bones."""
    counts = np.asarray(counts, dtype=np.float64)
    log = np.log10(np.maximum(np.asarray(errors, dtype=np.float64), 1e-15))
    if counts.size < 3 or not log[0] > log[-1]:
        return int(counts[0])
    x = (counts - counts[0]) / (counts[-1] - counts[0])
    y = (log - log[-1]) / (log[0] - log[-1])
    return int(counts[np.argmax((1.0 - x) - y)])


def choose_bone_count(vertices, rest, diagonal, max_bones=AUTO_MAX_BONES):
    """The :class:`BoneCount` of the examples vertices (F, V, 3), rest pose (V, 3) of rest
    ``diagonal``: the elbow of their rigid-cluster error curve up to ``max_bones`` (module notes)."""
    counts, errors = rigid_cluster_errors(vertices, rest, max_bones, diagonal)
    count = 1 if errors[0] <= EXACT else elbow(counts, errors)
    return BoneCount(count=count, counts=counts, errors=errors, rule=RULE.format(int(counts[-1])))

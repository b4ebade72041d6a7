"""Plug-in-Gait marker layout on the rest pose of the vlasic_samba capture (docs/markers/README.md).

    python docs/markers/make_samba_layout.py ../shared/data/vlasic_samba > docs/markers/vlasic_samba.layout.json
    python docs/markers/make_samba_layout.py ../shared/data/vlasic_samba --check [--take T.c3d] \
        [--png docs/markers/vlasic_samba_layout.png] > /dev/null

prints {label: vertex} (JSON) for 20 Plug-in-Gait labels. Every vertex comes from a geometric rule
on frame 0 (the rest pose ``fit-skin`` uses by default: ``--rest-frame 0``), in the performer's own
axes (lateral, forward, up); no vertex id is typed in. ``--check`` writes to stderr the checks
of README.md: distinct vertices, segment lengths over all frames, and proportions beside the first
frame of a Plug-in-Gait take; ``--png`` draws the check image.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from skinsynth.formats.meshseq import read_mesh_sequence

REST_FRAME = 0
ORDER = ("LFHD", "RFHD", "C7", "CLAV", "LSHO", "RSHO", "LELB", "RELB", "LWRA", "RWRA", "LFIN", "RFIN",
         "LASI", "RASI", "LKNE", "RKNE", "LANK", "RANK", "LTOE", "RTOE")
# Landmark heights above the floor as shares of the stature H (crown to sole), adult female means
# rounded (ANSUR II: cervicale 0.856, suprasternale 0.815, lateral femoral epicondyle ≈ 0.28,
# lateral malleolus 0.041; ASIS ≈ 0.55).
C7_H, CLAV_H, ASIS_H, KNEE_H, MALLEOLUS_H = 0.855, 0.815, 0.55, 0.28, 0.04
FOREHEAD = 0.045  # LFHD/RFHD band: this share of H below the crown (the temples)
TEMPLE = np.radians(60)  # LFHD/RFHD: the head surface facing this far round from straight ahead
UPPER_ARM = 0.56  # elbow: share of the acromion→wrist distance (Drillis–Contini 0.186 H / (0.186 + 0.146) H)
METATARSAL = 0.75  # metatarsal heads: share of the heel→toe-tip length
KNUCKLE = 0.45  # LFIN, just short of the 2nd metacarpal head: share of the wrist→fingertip length
ASIS_WIDTH = 0.7  # ASIS lateral offset: share of the trunk's half-width at ASIS height (22 cm apart here)
TILE = 0.01  # half-thickness of the bands, slabs and columns the rules search in (mesh units: metres)


def load(path):
    """The capture as the benchmarks pass it: a folder ``name`` holds ``name.npz``."""
    path = Path(path)
    spec = path / f"{path.name}.npz" if path.is_dir() and (path / f"{path.name}.npz").exists() else path
    return read_mesh_sequence(str(spec))


def body_frame(seq, frame=REST_FRAME):
    """(V, 3) coordinates (lateral: + is the performer's LEFT, forward, up from the floor), the
    stature H and the (3, 3) world→body rotation. Up is the file's up axis; forward points from
    the shins to the feet (feet reach forward of the ankles), left = up × forward (right-handed)."""
    v = seq.vertices[frame]
    u = np.eye(3)[{"X": 0, "Y": 1, "Z": 2}[seq.scene.up_axis]]
    h = v @ u - (v @ u).min()
    H = h.max()
    feet, shins = h < 0.03 * H, (h > 0.08 * H) & (h < 0.15 * H)
    f = v[feet].mean(0) - v[shins].mean(0)
    f -= (f @ u) * u
    f /= np.linalg.norm(f)
    left = np.cross(u, f)
    R = np.stack([left, f, u])
    P = (v - v[h > 0.93 * H].mean(0)) @ R.T  # origin under the crown: lateral 0 is the midline
    P[:, 2] = h
    return P, H, R


def parts(P, faces, H, count, shares):
    """Vertex index arrays, ordered by lateral, of the `count` pieces (≥ 2 % of V each) the mesh
    falls into below a horizontal cut. The cuts (`shares` of H) are tried in order; of the first
    run of cuts giving `count` pieces, the highest wins: the two legs below the skirt's hem
    (count 2, cuts going up from the ankles) or the two arms and the body below the armpits
    (count 3, cuts going down from the crown)."""
    found = None
    for cut in np.asarray(shares) * H:
        below = P[:, 2] < cut
        e = faces[below[faces].all(1)]
        graph = coo_matrix((np.ones(e.size), (e.ravel(), np.roll(e, 1, 1).ravel())), shape=(len(P),) * 2)
        label = np.where(below, connected_components(graph, directed=False)[1], -1)
        ids, n = np.unique(label[below], return_counts=True)
        big = ids[n >= 0.02 * len(P)]
        if len(big) == count and (found is None or cut > found[0]):
            found = cut, sorted((np.flatnonzero(label == i) for i in big), key=lambda i: P[i, 0].mean())
        elif found is not None:
            break
    if found is None:
        raise ValueError(f"no horizontal cut splits the mesh into {count} pieces")
    return found[1]


def pick(idx, score):
    """The vertex of `idx` where (V,) `score` is largest."""
    return int(idx[np.argmax(score[idx])])


def band(P, height, idx=None):
    """Indices (of `idx`, default all) within TILE of `height` above the floor."""
    idx = np.arange(len(P)) if idx is None else idx
    return idx[np.abs(P[idx, 2] - height) < TILE]


def slab(P, idx, origin, axis, t):
    """Indices of `idx` within TILE of the plane through origin + t·axis across the unit `axis`."""
    return idx[np.abs((P[idx] - origin) @ axis - t) < TILE]


def across(direction, axis):
    """`direction` less its part along the unit `axis`, normalised."""
    d = direction - (direction @ axis) * axis
    return d / np.linalg.norm(d)


def outermost(P, section, direction):
    """The vertex of `section` farthest along `direction` among those within 2 cm fore/aft of the
    section's middle (a lateral bony point sits at mid-depth of the limb, not at a back edge)."""
    fwd = P[section, 1]
    middle = (fwd.min() + fwd.max()) / 2
    return pick(section[np.abs(fwd - middle) < 2 * TILE], P @ direction)


def layout(P, faces, H):
    lat, fwd, up = P.T
    LEFT, FWD = np.eye(3)[:2]
    out = {}
    every = np.arange(len(P))
    trunk_and_arms = parts(P, faces, H, 3, np.arange(1.0, 0.3, -0.005))  # right arm, body, left arm (lateral order)
    legs = parts(P, faces, H, 2, np.arange(0.05, 0.5, 0.005))  # right leg, left leg: below the skirt's hem
    # Midline landmarks: extremes of a 2 cm-wide midline column in a band at the landmark height.
    mid = every[np.abs(lat) < TILE]
    out["C7"] = pick(band(P, C7_H * H, mid), -fwd)  # the backmost point at the neck's base
    out["CLAV"] = pick(band(P, CLAV_H * H, mid), fwd)  # the frontmost point at the jugular notch
    for s, L in ((1, "L"), (-1, "R")):
        side = every[s * lat > 0]
        # Head: over the temple, the point of the forehead band facing TEMPLE round from the front.
        out[L + "FHD"] = pick(band(P, up.max() - FOREHEAD * H, side), np.cos(TEMPLE) * fwd + np.sin(TEMPLE) * s * lat)
        # Shoulder (acromion): the top of the shoulder cap over the upper arm: of the mesh above
        # the arm piece's topmost ring (the armpit) and within 2 cm of its lateral position, the
        # highest point within 2 cm of the cap's fore/aft middle.
        arm = trunk_and_arms[0 if s < 0 else 2]
        ring = P[arm[up[arm] > up[arm].max() - TILE]].mean(0)
        cap = every[(np.abs(lat - ring[0]) < 2 * TILE) & (up > ring[2])]
        middle = (fwd[cap].min() + fwd[cap].max()) / 2
        out[L + "SHO"] = pick(cap[np.abs(fwd[cap] - middle) < 2 * TILE], up)
        acromion = P[out[L + "SHO"]]
        # Wrist: the narrowest 2 cm slab of the arm between 50 % and 85 % of the way from the
        # armpit ring to the fingertip (the arm point farthest from the ring).
        tip = P[pick(arm, np.linalg.norm(P - ring, axis=1))]
        axis = (tip - ring) / np.linalg.norm(tip - ring)
        steps = np.linspace(0.5, 0.85, 36) * np.linalg.norm(tip - ring)
        spread = [np.linalg.norm(P[sl] - P[sl].mean(0), axis=1).mean() for sl in
                  (slab(P, arm, ring, axis, t) for t in steps)]
        wrist_slab = slab(P, arm, ring, axis, steps[np.argmin(spread)])
        wrist = P[wrist_slab].mean(0)
        # LWRA: thumb side of the wrist = its front, across the forearm (the arms hang at the sides,
        # palms to the thighs, so the thumbs point forward; the mesh's closed hands do not show it).
        fore = (wrist - acromion) / np.linalg.norm(wrist - acromion)
        out[L + "WRA"] = pick(wrist_slab, P @ across(FWD, fore))
        # LFIN: back of the hand (lateral), index side (front), just short of the knuckles.
        hand_axis = (tip - wrist) / np.linalg.norm(tip - wrist)
        knuckles = slab(P, arm, wrist, hand_axis, KNUCKLE * np.linalg.norm(tip - wrist))
        out[L + "FIN"] = pick(knuckles, P @ across(s * LEFT + 0.5 * FWD, hand_axis))
        # LELB: lateral epicondyle, the outermost point of the arm's section across the
        # acromion→wrist line at the elbow's share of its length.
        elbow = slab(P, arm, acromion, fore, UPPER_ARM * np.linalg.norm(wrist - acromion))
        out[L + "ELB"] = outermost(P, elbow, across(s * LEFT, fore))
        # LASI: the frontmost point at ASIS height, ASIS_WIDTH of the trunk's half-width out.
        body = band(P, ASIS_H * H, trunk_and_arms[1])
        half = (s * lat[body]).max()
        out[L + "ASI"] = pick(body[np.abs(s * lat[body] - ASIS_WIDTH * half) < TILE], fwd)
        # Foot: its long axis from the leg's sole (lowest 3 % of H), heel to toe tip along forward.
        leg = legs[0 if s < 0 else 1]
        shin = P[leg[(up[leg] > 0.08 * H) & (up[leg] < 0.15 * H)]].mean(0)
        sole = leg[up[leg] < 0.03 * H]
        heel, toe = fwd[sole].min(), fwd[sole].max()
        # LTOE: the vertex nearest the point over the metatarsal heads on the foot's midline there,
        # as high as the foot's top at that station.
        foot = leg[up[leg] < 0.1 * H]
        station = foot[np.abs(fwd[foot] - heel - METATARSAL * (toe - heel)) < TILE]
        target = np.array([lat[station].mean(), heel + METATARSAL * (toe - heel), up[station].max()])
        out[L + "TOE"] = pick(foot, -np.linalg.norm(P - target, axis=1))
        # LANK: lateral malleolus, the outermost point of the ankle (within 3 cm fore/aft of the
        # shin's axis) at malleolus height.
        ankle = band(P, MALLEOLUS_H * H, leg)
        out[L + "ANK"] = pick(ankle[np.abs(fwd[ankle] - shin[1]) < 3 * TILE], s * lat)
        # LKNE: the knee joint (≈ 0.28 H) lies at the skirt's hem, and the leg piece's top bands
        # take in the hem. The knee band is the highest 2 cm band (below KNEE_H) whose section
        # is still leg-sized (each horizontal extent ≤ 1.5 × the shank's at 0.2 H); the marker is
        # its outermost point: the lateral knee just below the joint line, on the leg's skin.
        def extent(h):
            b = band(P, h, leg)
            return np.ptp(P[b, :2], axis=0) if len(b) else np.full(2, np.inf)
        heights = np.arange(0.2 * H, min(KNEE_H * H, up[leg].max() - TILE), 0.005)  # whole bands of leg
        clean = np.array([(extent(h) <= 1.5 * extent(0.2 * H)).all() for h in heights])
        first_bad = len(heights) if clean.all() else np.argmin(clean)
        knee = heights[max(first_bad - 1, 0)]
        out[L + "KNE"] = outermost(P, band(P, knee, leg), s * LEFT)
    return {k: out[k] for k in ORDER}


# --------------------------------------------------------------------------- checks (--check, --png)
SEGMENTS = (("LSHO", "LELB"), ("RSHO", "RELB"), ("LELB", "LWRA"), ("RELB", "RWRA"), ("LWRA", "LFIN"),
            ("RWRA", "RFIN"), ("LKNE", "LANK"), ("RKNE", "RANK"), ("LANK", "LTOE"), ("RANK", "RTOE"),
            ("LASI", "RASI"), ("LFHD", "RFHD"), ("C7", "CLAV"), ("LSHO", "RSHO"), ("LASI", "LKNE"),
            ("RASI", "RKNE"), ("LFHD", "C7"))


def check_segments(seq, ids, H, log):
    """Over every frame, each segment's length: mean and (max − min) as shares of the height."""
    log(f"segment lengths over {len(seq.vertices)} frames, as % of the rest height H = {H:.3f}:")
    log(f"  {'segment':<12}{'rest':>7}{'mean':>7}{'min':>7}{'max':>7}{'range':>7}{'std':>6}")
    for a, b in SEGMENTS:
        d = np.linalg.norm(seq.vertices[:, ids[a]] - seq.vertices[:, ids[b]], axis=1) / H * 100
        log(f"  {a + '-' + b:<12}{d[REST_FRAME]:7.1f}{d.mean():7.1f}{d.min():7.1f}{d.max():7.1f}"
            f"{np.ptp(d):7.1f}{d.std():6.1f}")


LENGTHS = (("shoulder width", "LSHO", "RSHO"), ("pelvis width (ASIS)", "LASI", "RASI"),
           ("head width (FHD)", "LFHD", "RFHD"), ("neck depth C7-CLAV", "C7", "CLAV"),
           ("upper arm L", "LSHO", "LELB"), ("upper arm R", "RSHO", "RELB"), ("forearm L", "LELB", "LWRA"),
           ("forearm R", "RELB", "RWRA"), ("hand L (WRA-FIN)", "LWRA", "LFIN"),
           ("thigh L (ASI-KNE)", "LASI", "LKNE"), ("thigh R (ASI-KNE)", "RASI", "RKNE"),
           ("shank L", "LKNE", "LANK"), ("shank R", "RKNE", "RANK"),
           ("foot L (ANK-TOE)", "LANK", "LTOE"), ("wrist to ankle L", "LWRA", "LANK"),
           ("shoulder to ankle L", "LSHO", "LANK"))


def check_take(take, points, log):
    """The layout's markers on the rest pose beside the take's first frame (metres, Z up; floor at
    Z = 0): each marker's height above the floor, and segment lengths, as shares of the head
    markers' height (mean of LFHD and RFHD) and in metres."""
    import ezc3d

    c = ezc3d.c3d(str(take))
    names = [n.split(":")[-1] for n in c["parameters"]["POINT"]["LABELS"]["value"]]
    unit = 1e-3 if c["parameters"]["POINT"]["UNITS"]["value"][0].strip("\0 ") == "mm" else 1.0
    T = dict(zip(names, c["data"]["points"][:3, :, 0].T * unit))
    head = {"samba": (points["LFHD"][2] + points["RFHD"][2]) / 2, "take": (T["LFHD"][2] + T["RFHD"][2]) / 2}
    log(f"take {Path(take).name}, frame 0 (standing, arms down) beside the samba rest pose; head markers' "
        f"height: samba {head['samba']:.3f} m, take {head['take']:.3f} m "
        f"(take/samba {head['take'] / head['samba']:.2f})")
    log(f"  {'height above floor / head height':<34}{'samba':>7}{'take':>7}")
    for k in points:
        log(f"  {k:<34}{points[k][2] / head['samba']:7.3f}{T[k][2] / head['take']:7.3f}")
    log(f"  {'length':<22}{'samba m':>8}{'take m':>8}{'samba/hd':>9}{'take/hd':>8}{'ratio':>7}"
        "   (ratio: take/samba of /hd)")
    for name, a, b in LENGTHS:
        m, t = np.linalg.norm(points[a] - points[b]), np.linalg.norm(T[a] - T[b])
        log(f"  {name:<22}{m:8.3f}{t:8.3f}{m / head['samba']:9.3f}{t / head['take']:8.3f}"
            f"{(t / head['take']) / (m / head['samba']):7.2f}")


VIEWS = (("front (her left on the right)", 0, 1, 1), ("back", 0, -1, -1),  # title, x axis, x sign, depth sign
         ("from her left", 1, -1, 1), ("from her right", 1, 1, -1))


def draw(P, faces, ids, path):
    """The rest mesh from the front, back and both sides, each marker drawn where no mesh lies
    well in front of it: red her left, blue her right, green midline."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    # Face normals for shading. The faces wind outward in world axes, but (left, forward, up)
    # is a left-handed frame, so the cross product points inward here: negate.
    n = -np.cross(P[faces[:, 1]] - P[faces[:, 0]], P[faces[:, 2]] - P[faces[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-12
    fig, axes = plt.subplots(1, 4, figsize=(15, 8))
    for ax, (title, h, sign, near) in zip(axes, VIEWS):
        x, depth = sign * P[:, h], near * P[:, 1 - h]  # depth: towards the viewer
        order = np.argsort(depth[faces].mean(1))  # far faces first
        tri = np.stack([x[faces], P[faces, 2]], -1)[order]
        shade = 0.45 + 0.5 * np.clip(near * n[order, 1 - h], 0, 1)
        ax.add_collection(PolyCollection(tri, facecolors=np.repeat(shade[:, None], 3, 1), edgecolors="none"))
        placed = []
        for k, i in ids.items():
            close = np.hypot(x - x[i], P[:, 2] - P[i, 2]) < TILE
            if depth[i] < depth[close].max() - 4 * TILE:
                continue  # hidden: mesh over 4 cm in front of it within 1 cm on the image
            c = "tab:red" if k[0] == "L" else "tab:blue" if k[0] == "R" else "tab:green"
            # A label goes outwards (midline ones to the right) unless another label is there
            # (a label spans about 0.24 m by 0.035 m), then a little lower or higher, or inwards.
            def free(right, y, w=0.24):
                lo = x[i] if right else x[i] - w
                return all(abs(y - b) > 0.035 or lo + w < a or a + w < lo for a, b in placed)
            outward = x[i] >= np.median(x) or k[0] not in "LR"
            right, y = next(((r, P[i, 2] + dy) for r in (outward, not outward) for dy in (0, -0.04, 0.04, -0.08)
                             if free(r, P[i, 2] + dy)), (outward, P[i, 2]))
            placed.append((x[i] if right else x[i] - 0.24, y))
            ax.plot(x[i], P[i, 2], "o", ms=5, color=c, mec="k", mew=0.6)
            ax.annotate(f"{k} {i}", (x[i], P[i, 2]), xytext=(x[i] + (0.02 if right else -0.02), y),
                        fontsize=7.5, color=c, ha="left" if right else "right", va="center", fontweight="bold")
        ax.set_xlim(x.min() - 0.12, x.max() + 0.12)
        ax.set_ylim(-0.02, P[:, 2].max() + 0.03)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=6)
    fig.suptitle("vlasic_samba rest pose (frame 0), Plug-in-Gait layout: label vertex (red her left, blue her "
                 "right, green midline); axes in metres: lateral or forward, height above the floor", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=72)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("capture")
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--take", default="../shared/data/mocap_c3d/kinematics_tennis_serve.c3d")
    parser.add_argument("--png")
    args = parser.parse_args()
    seq = load(args.capture)
    P, H, R = body_frame(seq)
    faces = np.asarray(seq.faces)
    ids = layout(P, faces, H)
    print(json.dumps(ids, indent=1))
    if args.check:
        def log(line):
            print(line, file=sys.stderr)
        log(f"rest frame {REST_FRAME}; up {seq.scene.up_axis}; forward {np.round(R[1], 3)}; "
            f"performer's left {np.round(R[0], 3)} (world axes); {len(ids)} markers, "
            f"{len(set(ids.values()))} distinct vertices")
        check_segments(seq, ids, H, log)
        if args.take and Path(args.take).exists():
            check_take(args.take, {k: P[i] for k, i in ids.items()}, log)
    if args.png:
        draw(P, faces, ids, args.png)


if __name__ == "__main__":
    main()

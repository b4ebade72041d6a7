"""fit-skin's playback of its capture: do the feet stay as the capture has them (issue 64)?

One JSON line per case: ``fit-skin INPUT --bones B --seed 0 --json`` run as a user runs it, once
at the defaults (the fit weighed toward the ground contacts) and once with ``--no-contacts`` (the
plain fit), each timed as the whole command. Reported from the summaries (docs/contact.md has the
definitions; shares of the height): the capture's and each playback's slide median, 95th
percentile and share of contact steps sliding over 0.5 %, their ratios to the capture's, the RMSE
and the time of the default over the plain fit's, and whether issue 64's goals hold (slide
median and p95 ≤ 1.2× the capture's, sliding steps ≤ max(1.5 × the capture's, 0.03), RMSE ≤
1.05×, time ≤ 1.2×).

Cases: the shared captures with a ground (vlasic_samba, vlasic_crane, geomvideo_dance, horse_gallop;
``datasets.BONES`` bones), the generated walkers (``walker``: in place, its feet slide as a
treadmill's; ``walker_planted``: feet that truly plant; ``walker_pivot``: a foot that turns on its
ball), and the samba again mirrored (x → −x, the
faces' winding turned) and Z up in centimetres (``--up-axis Z --meters-per-unit 0.01``): a rule that
holds only for one handedness, axis or unit is no rule.

    python benchmarks/fit_contacts.py --work /tmp/fit_contacts [--only vlasic_samba]
"""

import argparse
import json
import pathlib

import numpy as np

from datasets import BONES, captures, run, walker_inputs

CASES = ("vlasic_samba", "vlasic_crane", "geomvideo_dance", "horse_gallop")


def variants(work, name, path):
    """(case, input path, extra fit-skin options) of the samba's mirrored and Z-up centimetre takes."""
    with np.load(path) as data:
        vertices, faces = np.asarray(data["vertices"], np.float64), np.asarray(data["faces"])
    mirrored = vertices * np.array([-1.0, 1.0, 1.0])
    out = [(f"{name}_mirrored", mirrored, faces[:, ::-1], [])]
    z_up = np.stack([vertices[..., 0], -vertices[..., 2], vertices[..., 1]], axis=-1) * 100.0
    out.append((f"{name}_z_up_cm", z_up, faces, ["--up-axis", "Z", "--meters-per-unit", "0.01"]))
    for case, v, f, options in out:
        target = pathlib.Path(work) / f"{case}.npz"
        if not target.exists():
            np.savez_compressed(target, vertices=v.astype(np.float32), faces=f)
        yield case, str(target), options


def fit(work, case, path, bones, options):
    """The goals' figures of one case (module notes)."""
    summaries = {}
    for mode, extra in (("plain", ["--no-contacts"]), ("contacts", [])):
        seconds, _, _, stdout = run(["fit-skin", path, "-o", f"{case}.{mode}.skin.h5", "--bones", str(bones), "--seed",
                                     "0", "--json", "-q", *options, *extra], work)
        summaries[mode] = dict(json.loads(stdout.strip().splitlines()[-1]), wall_seconds=seconds)
    plain, ours = summaries["plain"], summaries["contacts"]
    line = {"case": case, "bones": bones, "rmse_ratio": ours["rmse"] / plain["rmse"],
            "time_ratio": ours["wall_seconds"] / plain["wall_seconds"], "seconds": ours["wall_seconds"],
            "plain_seconds": plain["wall_seconds"]}
    feet = ours.get("contacts")
    if feet is None:
        return {**line, "contacts": "no ground found"}
    capture = feet["capture"]
    line["weighed"] = feet["weighed"]
    line["capture"] = {k: capture.get(k) for k in ("slide_median", "slide_p95", "sliding_share")}
    for mode, summary in summaries.items():
        playback = summary["contacts"]["playback"]
        line[mode] = {k: playback.get(k) for k in ("slide_median", "slide_p95", "sliding_share")}
        line[f"{mode}_ratios"] = summary["contacts"]["ratios"]
    r, share = line["contacts_ratios"], line["contacts"]["sliding_share"]
    line["goals"] = {
        "slide_median": r["slide_median"] is None or r["slide_median"] <= 1.2,
        "slide_p95": r["slide_p95"] is None or r["slide_p95"] <= 1.2,
        "sliding_share": share is None or share <= max(1.5 * (capture.get("sliding_share") or 0.0), 0.03),
        "rmse": line["rmse_ratio"] <= 1.05, "time": line["time_ratio"] <= 1.2}
    return line


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", required=True, type=pathlib.Path, help="folder for the fits (kept)")
    parser.add_argument("--only", help="one case (a capture, walker, walker_planted, walker_pivot or a samba variant)")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    work = str(args.work)
    cases = []
    for name, path in captures(work):
        if name in CASES:
            cases.append((name, path, BONES[name], []))
            if name == "vlasic_samba":
                cases += [(case, p, BONES[name], options) for case, p, options in variants(work, name, path)]
    walkers = ("walker", "walker_planted", "walker_pivot")
    cases += [(name, path, BONES.get(name, 20), []) for name, path in walker_inputs(work, walkers, only=args.only)]
    for case, path, bones, options in cases:
        if args.only in (None, case):
            print(json.dumps(fit(work, case, path, bones, options)), flush=True)


if __name__ == "__main__":
    main()

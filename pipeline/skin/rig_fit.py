"""The rig a ``fit-skin`` request asks for, in one call: a free fit (:func:`.skin_fit.fit_skin`),
new clips' bone transforms on a given rig (:func:`.skin_fit.fit_bones_to_rig`, ``--rig``), a
free fit whose joints and tree are found and then held (:func:`.joints.find_skeleton`,
:func:`.jointed_fit.fit_jointed`, ``--skeleton``; Le & Deng 2014), or a rig fitted under a
skeleton the user brings (:func:`.jointed_fit.fit_given_skeleton`, ``--skeleton FILE``)."""

import numpy as np

#: Iterations of each phase of a jointed fit: joints moving, then fixed inside the body (:mod:`.jointed_fit`).
JOINTED_ITERATIONS = 40


def fit_rest_pose(first_input, vertices, clips, rig, bones, rest_frame, max_influences, iterations, root_bone,
                  transform_steps, surplus=0.0):
    """(bones, the rest frame, the rest pose's bounding-box diagonal) of a fit-skin request on the
    examples vertices (F, V, 3) of ``clips`` (a :class:`~..inputs.clips.Clips`), refused
    (OptionError) before the fit starts: options no fit can honour, a fit larger than the memory
    available, a rest pose with no extent (``first_input`` names the input). With ``rig`` (a
    skin record: ``bones``, ``rest_vertices``) its bones and rest pose. With ``surplus``
    (``--surplus-bones``) the memory and the vertex count are checked for the larger fit, of
    ``round((1 + surplus) · bones)`` bones. ``bones`` "auto": the count at the elbow of the clips'
    error against bones (:func:`.bone_count.choose_bone_count`), returned as a fourth value, the
    :class:`.bone_count.BoneCount` (None otherwise)."""
    from ..errors import OptionError
    from ..runtime.resources import check_memory
    from .skin_fit import fit_memory_bytes, validate_fit_options

    frames, count = vertices.shape[:2]
    chosen = None
    if rig is not None:
        if bones is not None and bones != rig.bones:
            raise OptionError(f"--bones {bones} differs from the rig's {rig.bones} bones (leave --bones out with --rig)")
        bones = rig.bones
        rest_frame = 0  # the rest pose is the rig's, not one of these frames (docs/format.md: /mesh)
    else:
        rest_frame = clips.frame(rest_frame, "--rest-frame")
        if bones == "auto":
            from .bone_count import choose_bone_count

            diagonal = _rest_diagonal(first_input, vertices[rest_frame])
            chosen = choose_bone_count(vertices, vertices[rest_frame], diagonal)
            bones = chosen.count
        validate_fit_options(frames, count, bones, max_influences, iterations, rest_frame)
        if root_bone is not None and root_bone >= bones:
            raise OptionError(f"--root-bone {root_bone} is not one of the {bones} bones (0..{bones - 1})")
        grown = int(round((1.0 + surplus) * bones))
        if grown > count:
            raise OptionError(f"--surplus-bones {surplus:g} grows {grown} bones, more than the mesh's {count} vertices")
        check_memory(fit_memory_bytes(frames, count, grown, transform_steps),
                     f"fit-skin --bones {bones} on {count} vertices × {frames} frames"
                     + (f" with --transform-steps {transform_steps}" if transform_steps else "")
                     + (f" grown from {grown} bones (--surplus-bones)" if grown > bones else ""))
    if chosen is None:
        diagonal = _rest_diagonal(first_input, rig.rest_vertices if rig is not None else vertices[rest_frame])
    return bones, rest_frame, diagonal, chosen


def _rest_diagonal(first_input, rest):
    """The rest pose's (V, 3) bounding-box diagonal, refused (OptionError) where it has no extent."""
    from ..errors import OptionError
    from ..mesh.geometry import bounding_box_diagonal

    diagonal = bounding_box_diagonal(rest)
    if not diagonal > 0.0:
        raise OptionError(f"{first_input}: the rest frame has no extent (all vertices coincide)")
    return diagonal


def fit_rig(vertices, faces, bones, rig=None, given=None, find_joints=False, root_bone=None, max_joint_drift=None,
            max_influences=4, iterations=100, rest_frame=0, seed=0, tolerance=0.02, patience=5, joint_steps=0,
            device=None, diagonal=1.0, surplus=0.0, up_axis="Y", max_sliding_share=None, near=None,
            contact_weight=None, progress=lambda phase, length: None):
    """The rig of the examples ``vertices (F, V, 3)`` (faces (T, 3)), fitted as asked.

    ``rig``: a skin (rest_vertices (V, 3), bone_indices (V, K), bone_weights (V, K), bones) whose
    rig is kept, only the bone transforms solved; ``given``: a :class:`.joints.Skeleton` to fit
    under (one bone per joint; the rest pose is frame ``rest_frame``); ``find_joints``: after the
    free fit of ``bones`` bones (its bones that dominate no vertex put where it lacks one, unless
    ``root_bone`` numbers them: :mod:`.helper_bones`), find its joints (``root_bone``, ``max_joint_drift`` over the rest
    ``diagonal``, at most ``max_sliding_share`` of the bones sliding: None for
    :data:`.joints.MAX_SLIDING_SHARE`) and refit so that they hold; with ``surplus`` > 0, grown from more bones and
    pruned instead (:func:`.bone_pruning.fit_pruned_skeleton`; no free fit of ``bones`` then,
    its RMSE NaN); its chains named from the geometry, ``up_axis`` ("Y" or "Z") up
    (:func:`~skinsynth.pipeline.rig.chain_labels.chain_labels`). The other options are
    :func:`.skin_fit.fit_skin`'s
    (``joint_steps``: its ``--transform-steps``). ``near`` (F, V) bool: the (frame, vertex) pairs
    near the capture's ground, whose residuals the free fit then weighs more
    (:func:`.contact_fit.keep_contacts`, ``contact_weight``: None for its default), so that the
    rig replays the capture's contacts still (None: no ground, or ``--no-contacts``; not with
    ``rig``, ``given``, ``find_joints`` or ``surplus``, whose fits start from or keep other bones).
    ``progress(phase, length)`` is called as each
    phase starts, ``"fit"`` (the free fit or the rig's, ``iterations`` long), ``"helpers"`` (the free
    fit again from its helper bones reseeded, :mod:`.helper_bones`), ``"joints"`` (the
    refit on found joints), ``"contacts"`` (``near``), ``"grow"`` and ``"prune"`` (``surplus``) or ``"given"`` (the fit
    under ``given``), and returns the phase's
    ``progress(iteration, rmse)`` (or None).

    Returns (a :class:`.skin_fit.SkinFit`, the /skin/skeleton record or None: parents (B,),
    jointed (B,), joints (B, 3), drift (B,), root, free_rmse (NaN under ``given`` and with
    ``surplus``: no free fit of ``bones``), max_drift)."""
    from ..errors import OptionError
    from .jointed_fit import fit_given_skeleton, fit_jointed
    from .joints import MAX_JOINT_DRIFT, MAX_SLIDING_SHARE, find_skeleton, hung_from_centre
    from .skin_fit import fit_bones_to_rig, fit_skin

    if (surplus or max_sliding_share is not None) and not find_joints:
        raise OptionError("--surplus-bones and --max-sliding-share apply only with a bare --skeleton (a skeleton found)")
    if surplus and root_bone is not None:
        raise OptionError("--surplus-bones does not combine with --root-bone (the bones are renumbered as they merge)")
    if given is not None:
        fitted, skeleton = fit_given_skeleton(vertices, vertices[rest_frame], faces, given,
                                              max_influences=max_influences, iterations=JOINTED_ITERATIONS,
                                              progress=progress("given", 2 * JOINTED_ITERATIONS))
        return fitted, _skeleton_record(skeleton, skeleton.drift, float("nan"), float("nan"), fitted)
    if rig is not None:
        return fit_bones_to_rig(vertices, rig.rest_vertices, rig.bone_indices, rig.bone_weights, rig.bones,
                                iterations=iterations, tolerance=tolerance, patience=patience,
                                joint_steps=joint_steps, progress=progress("fit", iterations), device=device), None
    max_drift = MAX_JOINT_DRIFT if max_joint_drift is None else max_joint_drift
    sliding_share = MAX_SLIDING_SHARE if max_sliding_share is None else max_sliding_share
    if surplus > 0.0:
        from .bone_pruning import fit_pruned_skeleton

        fitted, skeleton = fit_pruned_skeleton(vertices, faces, bones, surplus, max_influences=max_influences,
                                               iterations=iterations, rest_frame=rest_frame, seed=seed,
                                               tolerance=tolerance, patience=patience, joint_steps=joint_steps,
                                               device=device, max_drift=max_drift, max_sliding_share=sliding_share,
                                               jointed_iterations=JOINTED_ITERATIONS, diagonal=diagonal,
                                               progress=progress)
        skeleton, drift = hung_from_centre(skeleton, skeleton.drift, fitted.rest_vertices, fitted.bone_indices,
                                           fitted.bone_weights, vertices, "XYZ".index(up_axis))
        return fitted, _skeleton_record(skeleton, drift, float("nan"), max_drift, fitted, vertices, up_axis, faces)
    free = fit_skin(vertices, bones, max_influences=max_influences, iterations=iterations, rest_frame=rest_frame,
                    seed=seed, tolerance=tolerance, patience=patience, joint_steps=joint_steps, device=device,
                    progress=progress("fit", iterations))
    if not find_joints:
        if near is not None:
            from .contact_fit import CONTACT_ROUNDS, CONTACT_WEIGHT, keep_contacts

            free = keep_contacts(free, vertices, near, CONTACT_WEIGHT if contact_weight is None else contact_weight,
                                 max_influences=max_influences, device=device,
                                 progress=progress("contacts", CONTACT_ROUNDS))
        return free, None
    if root_bone is None:  # a bone that dominates no vertex is put where the fit lacks one (.helper_bones)
        from .helper_bones import HELPER_ROUNDS, reseed_helpers

        steps = []  # the phase is shown only where a helper is reseeded

        def refit(start):
            steps.append(steps[-1] if steps else progress("helpers", HELPER_ROUNDS * iterations))
            return fit_skin(vertices, bones, max_influences=max_influences, iterations=iterations,
                            rest_frame=rest_frame, seed=seed, tolerance=tolerance, patience=patience,
                            joint_steps=joint_steps, device=device, progress=steps[-1], start=start)
        free = reseed_helpers(free, vertices, refit)
    found = find_skeleton(free.rest_vertices, faces, free.bone_indices, free.bone_weights, free.rotations,
                          free.translations, root=root_bone, max_drift=max_drift, diagonal=diagonal,
                          max_sliding_share=sliding_share, frames=vertices, up_axis="XYZ".index(up_axis))
    fitted, skeleton = fit_jointed(vertices, free.rest_vertices, free.bone_indices, free.bone_weights, free.rotations,
                                   found, faces=faces, max_influences=max_influences, iterations=JOINTED_ITERATIONS,
                                   progress=progress("joints", JOINTED_ITERATIONS))
    loosened = _over_budget(found, fitted.rmse, free.rmse, max_drift, sliding_share,
                            max_joint_drift is None and max_sliding_share is None)
    if loosened is not None:  # over the error budget: the joints that cost most slide (JOINT_BUDGET)
        looser_drift, looser_share = loosened
        loose = find_skeleton(free.rest_vertices, faces, free.bone_indices, free.bone_weights, free.rotations,
                              free.translations, root=root_bone, max_drift=looser_drift, diagonal=diagonal,
                              max_sliding_share=looser_share, frames=vertices, up_axis="XYZ".index(up_axis))
        again, again_skeleton = fit_jointed(vertices, free.rest_vertices, free.bone_indices, free.bone_weights,
                                            free.rotations, loose, faces=faces, max_influences=max_influences,
                                            iterations=JOINTED_ITERATIONS, tolerance=SOFT_TOLERANCE,
                                            progress=progress("soft", JOINTED_ITERATIONS))
        if again.rmse < fitted.rmse:
            fitted, skeleton, found, max_drift = again, again_skeleton, loose, looser_drift
    drift = found.drift
    if root_bone is None:  # fitted from the heaviest bone, hung from the body's centre (issue 65)
        skeleton, drift = hung_from_centre(skeleton, drift, fitted.rest_vertices, fitted.bone_indices,
                                           fitted.bone_weights, vertices, "XYZ".index(up_axis))
    return fitted, _skeleton_record(skeleton, drift, free.rmse, max_drift, fitted, vertices, up_axis, faces)


#: The error a jointed rig may cost, over the free fit's (:func:`_over_budget`): past it, joints held
#: fixed beyond ``--max-joint-drift`` by the sliding-share bound slide instead (a soft body: a
#: simulated cow cost 2.1× with a fifth of its bones sliding; the summary says so), or, none held,
#: the most drifting joints slide up to that share; within it, a rig an animator poses turns at its
#: joints (issue 65: the shared captures' skeletons cost 1.14–1.47× the free fit's error).
JOINT_BUDGET = 1.5
#: The looser refit's stopping rule (:func:`fit_rig`: over the budget, with the drifting joints
#: sliding): it stops once three iterations improved the RMSE by at most 1 % (the jointed fit's own
#: rule is 0.2 %, :data:`.jointed_fit.TOLERANCE`). It is there to come under :data:`JOINT_BUDGET`,
#: and it crawls: Zheng's dancer's ran all 40 iterations, 1.29× the free fit's error at the 20th and
#: 1.24× at the 40th, its second half a fifth of the whole command's time (2.1–2.3× the free fit's,
#: where issue 65 asks 2×).
SOFT_TOLERANCE = 0.01


def _over_budget(found, rmse, free_rmse, max_drift, share, free_to_choose):
    """(max_drift, max_sliding_share) of a second, looser skeleton where the jointed rig of ``found``
    costs more than :data:`JOINT_BUDGET` × the free fit's error (``rmse`` against ``free_rmse``) and
    the user left both bounds to fit-skin (``free_to_choose``), else None. Joints held fixed past
    ``max_drift`` by the sliding-share bound: all of them slide (the share lifted: a soft body).
    None held, but room left under the share: the most drifting joints slide, as many as it allows
    (the drift bound lowered to theirs: Zheng's dancer holds every joint within 2 % of the diagonal
    at 1.58× the free fit's error; its five most drifting joints sliding, 1.30×, the looser refit
    stopped at :data:`SOFT_TOLERANCE`)."""
    from .joints import sliding_bound

    if not free_to_choose or not rmse > JOINT_BUDGET * free_rmse:
        return None
    if (found.jointed & (found.drift > max_drift)).any():
        return max_drift, None
    sliding = 0 if found.sliding is None else int(np.count_nonzero(found.sliding))
    room = sliding_bound(share, found.bones) - sliding
    drifts = np.sort(found.drift[found.jointed])[::-1]
    if room <= 0 or drifts.size == 0 or not drifts[0] > 0.0:
        return None
    return float(drifts[min(room, drifts.size) - 1]) * (1.0 - 1e-9), share


def _skeleton_record(skeleton, drift, free_rmse, max_drift, fitted, vertices=None, up_axis="Y", faces=None):
    """What /skin/skeleton stores of a fitted :class:`.joints.Skeleton` (docs/format.md); with
    sliding bones, each one's travel over the ``fitted`` frames (its slide's least and largest
    value per axis of its parent's frame, :func:`~skinsynth.pipeline.rig.skeleton.slide_offsets`):
    the bounds every later pose keeps it within. The bones' names: the skeleton's own (a given
    one's), else, given the examples ``vertices`` (F, V, 3), the ``up_axis`` and the mesh's ``faces``,
    its chains named (:func:`~skinsynth.pipeline.rig.chain_labels.chain_labels`; none where it finds no legs)."""
    from ..rig.chain_labels import chain_labels

    record = {"parents": skeleton.parents, "jointed": skeleton.jointed, "joints": skeleton.joints, "drift": drift,
              "root": skeleton.root, "free_rmse": free_rmse, "max_drift": max_drift, "names": skeleton.names}
    if skeleton.names is None and vertices is not None:
        record["names"] = chain_labels(skeleton.parents, skeleton.joints, fitted.rest_vertices, fitted.bone_indices,
                                       fitted.bone_weights, "XYZ".index(up_axis), vertices, jointed=skeleton.jointed,
                                       faces=faces)
    if skeleton.sliding is not None and skeleton.sliding.any():
        from ..rig.skeleton import slide_offsets

        bones = np.flatnonzero(skeleton.sliding)
        slides = slide_offsets(fitted.rotations, fitted.translations, skeleton.parents, skeleton.joints, bones)
        low, high = np.zeros((skeleton.bones, 3)), np.zeros((skeleton.bones, 3))
        low[bones], high[bones] = slides.min(axis=0), slides.max(axis=0)
        record.update(sliding=np.asarray(skeleton.sliding, bool), slide_low=low, slide_high=high)
    return record


def skin_summary(output, fit, frame_rmse, clips, diagonal, fps, scene, seconds, device, history, skeleton=None,
                 faces=None, feet=None, near=None, contact_weight=None, chosen=None):
    """``fit-skin``'s summary (--json) and its text lines, from a fit (:func:`fit_rig`) and its
    per-frame RMSE (F,) (:func:`.skin_fit.finish_fit`): the error over the rest bounding-box
    ``diagonal``, overall and per clip (``clips``: a :class:`~skinsynth.pipeline.inputs.clips.Clips`),
    the input's ``scene`` (units, up axis, start frame, prim path, as the USD written from it
    states them), the fit's ``history`` [(seconds, RMSE over the diagonal)]; with the
    ``skeleton`` record (and the mesh's ``faces`` (T, 3)), its joints (:func:`_skeleton_summary`);
    with ``feet`` (:func:`.contact_fit.playback_feet`: the capture has a ground), how the playback
    keeps the capture's feet, and with ``near`` (F, V) (the fit weighed toward them, at
    ``contact_weight``: None for the default) how many vertices were weighed and how much; with
    ``chosen`` (``--bones auto``: a :class:`.bone_count.BoneCount`) the count, its rule and the
    error of rigid clusters around it."""
    frames, bones = fit.rotations.shape[:2]
    count = fit.rest_vertices.shape[0]
    summary = {"output": output, "bones": bones, "vertices": int(count), "frames": int(frames), "fps": fps,
               "rmse": fit.rmse, "rmse_over_diagonal": fit.rmse / diagonal, "iterations": int(fit.iterations),
               "converged": bool(fit.converged), "stopped": fit.stopped, "seconds": round(seconds, 3),
               "device": device,
               "bones_without_weight": int(fit.bones_without_weight), "meters_per_unit": scene.meters_per_unit,
               "up_axis": scene.up_axis, "start_frame": scene.start_frame, "prim_path": scene.prim_path,
               "history": [[t, float(f"{e:.6g}")] for t, e in history]}
    clip_rmse = [float(np.sqrt(np.mean(frame_rmse[a:b] ** 2))) for a, b in zip(clips.starts[:-1], clips.starts[1:])]
    summary["clips"] = [{"name": name, "frames": int(n), "rmse": rmse, "rmse_over_diagonal": rmse / diagonal}
                        for name, n, rmse in zip(clips.names, clips.frames, clip_rmse)]
    lines = [f"wrote {output}: {bones} bones, {count} vertices, {frames} frames; "
             f"RMSE {fit.rmse:.4g} = {fit.rmse / diagonal:.2e} of the bounding-box diagonal "
             f"({fit.iterations} iterations, {fit.stopped}, {seconds:.1f} s)",
             f"scene: {scene.describe(frames)} at {fps:g} fps (stated again by every USD written "
             "from it; --meters-per-unit, --up-axis, --start-frame override)"]
    if chosen is not None:
        around = chosen.near()
        summary["bone_count"] = {"chosen": chosen.count, "rule": chosen.rule,
                                 "rigid_cluster_errors": [[k, e] for k, e in around]}
        lines.append(f"bones: auto chose {chosen.count}, {chosen.rule}; the RMSE of that many rigid clusters over "
                     f"the diagonal: " + ", ".join(f"{e:.2e} at {k}" for k, e in around)
                     + " (a finer fit: more bones; docs/own_capture.md)")
    if len(clips) > 1:
        lines.append("clips: " + ", ".join(f"{c['name']} ({c['frames']} frames, RMSE/diag {c['rmse_over_diagonal']:.2e})"
                                           for c in summary["clips"]))
    if skeleton is not None:
        summary["skeleton"], line = _skeleton_summary(skeleton, fit, faces, diagonal, "XYZ".index(scene.up_axis))
        lines.append(line)
    if feet is not None:
        summary["contacts"], line = _contacts_summary(feet, near, contact_weight)
        lines.append(line)
    return summary, lines


def _contacts_summary(feet, near, weight):
    """--json's "contacts" and its text line: the weighting (``near`` (F, V) or None: not weighed)
    and the playback's feet against the capture's (:func:`.contact_fit.playback_feet`)."""
    from ..mesh.contact_measures import significant
    from .contact_fit import CONTACT_WEIGHT, contact_weight

    out = significant(dict(feet))
    if near is None:
        out["weighed"] = None
        how = "not weighed (--no-contacts, --rig or --skeleton)"
    else:
        used = contact_weight(float(near.mean()), CONTACT_WEIGHT if weight is None else weight)
        out["weighed"] = {"vertices": int(near.any(axis=0).sum()), "pair_share": float(near.mean()), "weight": used}
        how = (f"{out['weighed']['vertices']} vertices near the ground weighed {used:.3g}× more "
               f"({near.mean():.1%} of the frame-vertex pairs)")
    c, p = out["capture"], out["playback"]

    def share(side, key):
        return f"{side[key]:.2%}" if side.get(key) is not None else "n/a"

    line = (f"ground contacts: {how}; the playback's feet against the capture's (shares of the height; "
            f"docs/contact.md): slide median {share(p, 'slide_median')} ({share(c, 'slide_median')}), 95th percentile "
            f"{share(p, 'slide_p95')} ({share(c, 'slide_p95')}), steps sliding over 0.5 % {share(p, 'sliding_share')} "
            f"({share(c, 'sliding_share')})")
    return out, line


#: The travel a sliding joint may have, as a share of the character's height (the rest pose's extent
#: along the up axis): a shoulder blade slides about 10 cm on a 1.75 m human (6 %), a horse's
#: shoulder on its trunk about as much. A bone that slides farther on its parent is not on a joint:
#: skin that moves on its own (a skirt panel, a belly, a simulated body), or a bone the fit spread
#: over two parts (the generated humanoid fitted with exactly its 17 bones, seed 0: a bone holding
#: half a shin and a foot slid 53 % of the height); fit-skin names it "loose".
SLIDE_LIMIT = 0.1


def _skeleton_summary(record, fit, faces, diagonal, up_axis=1):
    """--json's "skeleton" and its text line: the joints (how many inside the mesh), the sliding
    bones with their travel, the free bones, the largest drift, the error against the free fit's,
    the bones' names and the chains named (:func:`~skinsynth.pipeline.rig.chain_labels.named_chains`)."""
    from ..mesh.geometry import points_inside
    from ..rig.chain_labels import named_chains
    from .joints import MAX_SLIDING_SHARE, sliding_bound

    jointed = np.asarray(record["jointed"])
    sliding = np.asarray(record.get("sliding", np.zeros_like(jointed)), bool)
    inside = points_inside(np.asarray(record["joints"])[jointed | sliding], fit.rest_vertices, faces)
    free = int((~jointed & ~sliding).sum()) - 1
    travel = np.asarray(record.get("slide_high", 0.0)) - np.asarray(record.get("slide_low", 0.0))
    height = float(np.ptp(fit.rest_vertices[:, up_axis])) or 1.0
    summary = {"root": int(record["root"]), "joints": int(jointed.sum()), "free_bones": free,
               "sliding": [{"bone": int(b), "parent": int(record["parents"][b]),
                            "travel_over_diagonal": float(np.linalg.norm(travel[b]) / diagonal),
                            "travel_over_height": float(np.linalg.norm(travel[b]) / height)}
                           for b in np.flatnonzero(sliding)],
               "parents": [int(p) for p in record["parents"]],
               "joints_inside": int(inside.sum()), "largest_drift": float(np.max(record["drift"], initial=0.0)),
               "free_rmse": float(record["free_rmse"]), "rmse": float(fit.rmse), "names": record.get("names"),
               "held_fixed": [int(b) for b in np.flatnonzero(jointed & (np.asarray(record["drift"])
                                                                         > record["max_drift"]))],
               "rmse_over_free": float(fit.rmse / record["free_rmse"]) if record["free_rmse"] > 0 else None}
    # --skeleton FILE has no free fit to compare with (NaN stored; null here)
    summary["free_rmse"] = summary["free_rmse"] if np.isfinite(summary["free_rmse"]) else None
    ratio = f"{summary['rmse_over_free']:.2f}×" if summary["rmse_over_free"] is not None else "—"
    free_error = f" ({record['free_rmse'] / diagonal:.2e} of the diagonal)" if summary["free_rmse"] else ""
    given = np.isnan(record["max_drift"])  # --skeleton FILE; a found one without free fit: --surplus-bones
    slid = ", ".join(f"{s['bone']} on {s['parent']} ({s['travel_over_height']:.1%})" for s in summary["sliding"])
    summary["loose"] = [s["bone"] for s in summary["sliding"] if s["travel_over_height"] > SLIDE_LIMIT]
    parents = np.asarray(record["parents"])
    carrying = [b for b in summary["loose"] if (parents == b).any()]
    loose = (f"; loose: {', '.join(map(str, summary['loose']))} slide past {SLIDE_LIMIT:.0%} of the height on their "
             f"parents, no joint: skin moving on its own (cloth, soft tissue) or a bone the fit spread over two "
             f"parts (other --bones or --seed, or --surplus-bones, may joint it)"
             + (f"; {', '.join(map(str, carrying))} carr{'ies' if len(carrying) == 1 else 'y'} bones below"
                if carrying else "") if summary["loose"] else "")
    chains = named_chains(summary["names"])
    summary["chains"] = chains
    held = (f"; {len(summary['held_fixed'])} joint(s) drifting past --max-joint-drift held fixed (bones "
            f"{', '.join(map(str, summary['held_fixed']))}: the --max-sliding-share bound)"
            if summary["held_fixed"] else "")
    # more than the sliding-share bound slide: the error budget freed them (a soft body), or the user asked
    summary["soft"] = len(summary["sliding"]) > sliding_bound(MAX_SLIDING_SHARE, jointed.size)
    soft = (f"soft: {len(summary['sliding'])} of its {jointed.size - 1} bones slide (more than a fifth: held as "
            f"joints they cost more than {JOINT_BUDGET:g}× the free fit's error, or --max-sliding-share asked); "
            if summary["soft"] else "")
    line = (f"skeleton: {soft}root bone {summary['root']}, {summary['joints']} fixed joints and "
            f"{len(summary['sliding'])} sliding{f' ({slid} of the height)' if slid else ''} "
            f"({summary['joints_inside']} inside the mesh, "
            f"largest drift {summary['largest_drift']:.2%} of the diagonal), {free} free bone(s) under the root; "
            + (f"RMSE {ratio} the free fit's{free_error}" if summary["free_rmse"] else
               "given (--skeleton FILE)" if given else "grown from more bones (--surplus-bones)")
            + held + loose + (f"; chains {', '.join(f'{c} ({n})' for c, n in chains.items())}" if chains
                      else "; no chains named (no character's legs found: two or four feet it stands on, "
                           "each leg turning at fixed joints, its skin round; docs/skeleton.md)"))
    return summary, line

"""Synthesized animations as vertices, skinned on demand for the caches synthesize writes."""

from skinsynth.gpu import lbs


class SkinnedAnimations:
    """Each synthesized animation's vertices (M, V, 3), skinned by the warp LBS kernel only when
    asked for (a crowd of 10⁶ never has to fit in memory): ``skin`` has rest_vertices (V, 3),
    bone_indices and bone_weights (V, K); F (A, M, B, 3, 3) and t (A, M, B, 3) the bone motions;
    offsets (A, 3) each animation's placement.

    Asked in order (as the writers do), it skins the next ``threads`` animations in worker
    threads while the current one is written (CPU only: a CPU kernel launch runs in its calling
    thread, outside the GIL, so two threads skin about twice as fast on two cores)."""

    def __init__(self, skin, F, t, offsets, device, threads=1):
        self.skin, self.F, self.t, self.offsets, self.device = skin, F, t, offsets, device
        self.threads = threads if str(device).startswith("cpu") else 1
        self._pool, self._pending = None, {}

    def __len__(self):
        return self.F.shape[0]

    def _skin(self, a):
        s = self.skin
        return lbs(s.rest_vertices, s.bone_indices, s.bone_weights, self.F[a], self.t[a], device=self.device) \
            + self.offsets[a]

    def __getitem__(self, a):
        if self.threads <= 1:
            return self._skin(a)
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(self.threads)
        for stale in [b for b in self._pending if b < a]:
            self._pending.pop(stale).cancel()
        for b in range(a, min(len(self), a + self.threads + 1)):
            if b not in self._pending:
                self._pending[b] = self._pool.submit(self._skin, b)
        return self._pending.pop(a).result()

    def close(self):
        if self._pool is not None:
            for future in self._pending.values():
                future.cancel()
            self._pool.shutdown()
            self._pool, self._pending = None, {}


def measure_feet(skin, F, t, sources, starts, count, up_axis=1, device="cpu", block=64):
    """The feet figures (:mod:`.contact_measures`, docs/contact.md) of the input and of the first
    ``count`` synthesized animations, their vertices skinned in blocks of ``block`` frames:
    ``skin`` has examples (Fi, V, 3), rest_vertices, bone_indices, bone_weights; F (A, M, B, 3, 3),
    t (A, M, B, 3), sources (C, A, M); ``starts`` the input's clip starts (C + 1,). An output frame
    is measured against the ground of the clip its first component plays. Returns a dict: height,
    ground (per clip), input, output (:func:`~.contact_measures.summary`), ratios."""
    import numpy as np

    from .contact.measures import Steps, character_height, measure_frames, measure_input, ratios, summary

    height = character_height(skin.rest_vertices, up_axis)
    measured_in, grounds = measure_input(skin.examples, starts, height, up_axis, block=block)
    clip_of = np.clip(np.searchsorted(np.asarray(starts), np.asarray(sources[0, :count]), side="right") - 1,
                      0, len(grounds) - 1)
    parts = []
    for a in range(count):
        Fa, ta = np.asarray(F[a]), np.asarray(t[a])  # one animation's bones (a cluster's: read from its shard)

        def frames(s, e, Fa=Fa, ta=ta):
            return lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, Fa[s:e], ta[s:e], device=device)

        parts.append(measure_frames(frames, Fa.shape[0], grounds[clip_of[a]], height, up_axis, block=block))
    figures_in, figures_out = summary(measured_in), summary(Steps.join(parts))
    return {"height": height, "ground": [float(g) for g in grounds], "input": figures_in, "output": figures_out,
            "ratios": ratios(figures_out, figures_in)}

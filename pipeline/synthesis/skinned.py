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

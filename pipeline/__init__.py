"""skinsynth.pipeline: the algorithms, on arrays; no file is opened here.

One package per stage, over one shared floor (docs/architecture.md):

- :mod:`.skin`: fit-skin (Le & Deng's rigid-bone LBS decomposition, Zheng §3.1);
- :mod:`.puppet`: select-controls, train-kcca, evaluate and play's prediction (Feng 2008);
- :mod:`.synthesis`: build-graph and synthesize (Zheng 2013);
- :mod:`.view`: headless rendering and previews;
- the floor, which every stage may import: :mod:`.rig` (rotations, joint trees, influences,
  morph targets), :mod:`.mesh` (geometry, UV seams), :mod:`.inputs` (clips, the built-in
  examples), :mod:`.runtime` (the process pool and Dask, compiled loops) and :mod:`.errors`.

Stages never import each other; ``pipeline`` imports ``gpu`` through its public API and never
``formats`` or ``cli``.
"""

"""skinsynth as Make rules: every command writes exactly the path it is given, so a second
``make`` finds every target up to date and runs nothing."""

import os
import shutil
import subprocess
import sys

import pytest

from skinsynth.formats.meshseq import write_array_sequence
from skinsynth.pipeline.inputs.examples import bending_bar

SKINSYNTH = os.path.join(os.path.dirname(sys.executable), "skinsynth")

MAKEFILE = """\
S := {skinsynth}
all: skin.usda skin_vat.exr controls.h5 puppet.h5 crowd.usdc crowd_vat/ one.h5 graph.h5 synth.h5 synth_usd/ \\
\tsynth.mp4 puppet.png
skin.h5: bar.npz
\t$(S) fit-skin $< -o $@ --bones 4 --iterations 6 -q
skin.usda: skin.h5
\t$(S) export $< -o $@
skin_vat.exr: skin.h5
\t$(S) export $< -o $@
controls.h5: skin.h5
\t$(S) select-controls $< -o $@ --count 6 -q
puppet.h5: controls.h5
\t$(S) train-kcca $< -o $@ -q
crowd.usdc: puppet.h5 bar.npz
\t$(S) play $< -c bar.npz --instances 3 -o $@ --device cpu
crowd_vat/: puppet.h5 bar.npz
\t$(S) play $< -c bar.npz --instances 3 -o $@ --device cpu
one.h5: puppet.h5 bar.npz
\t$(S) play $< -c bar.npz -o $@ --device cpu
graph.h5: skin.h5
\t$(S) build-graph $< -o $@ --min-segment 4 -q
synth.h5 synth_usd/: graph.h5
\t$(S) synthesize $< -o synth.h5 -n 2 -m 30 --usd synth_usd -q
synth.mp4: synth.h5
\t$(S) preview $< -o $@ --animation 1 --size 64x48 -q
puppet.png: puppet.h5
\t$(S) preview $< -o $@ --size 64x48 -q
"""


@pytest.mark.skipif(shutil.which("make") is None or not os.path.exists(SKINSYNTH),
                    reason="needs make and the installed skinsynth command")
def test_every_rule_settles_after_one_make(tmp_path):
    vertices, faces = bending_bar(frames=40, rings=10, segments=8, cycles=2)
    write_array_sequence(tmp_path / "bar.npz", vertices, faces, 24.0)
    (tmp_path / "Makefile").write_text(MAKEFILE.format(skinsynth=SKINSYNTH))
    first = subprocess.run(["make", "-s"], cwd=tmp_path, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    # -q: exit 0 only if every target is up to date (nothing would run)
    again = subprocess.run(["make", "-q"], cwd=tmp_path, capture_output=True, text=True)
    assert again.returncode == 0, subprocess.run(["make", "-n"], cwd=tmp_path, capture_output=True, text=True).stdout
    assert {f"character_{c:03d}.exr" for c in range(3)} | {"vat.json"} <= set(os.listdir(tmp_path / "crowd_vat"))
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # no temporaries left

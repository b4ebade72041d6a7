# skinsynth: `make demo` sets up and runs the main job on a built-in example; `make test` sets up and runs the tests.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
DEMO   := build/demo

.PHONY: setup browser demo docs test test-fast bench blender blender-for-tests clean

JS     := tests/contracts/js

setup: $(VENV)/.installed $(VENV)/.precompiled $(JS)/node_modules/.installed browser

# The headless browser the tests of `skinsynth view` drive (Debian's chromium, through Playwright;
# Playwright's own browser download is never used): installed when missing and apt-get can run (as
# root, as CI does); otherwise setup goes on and those tests skip, naming `apt-get install chromium`.
browser:
	@if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing chromium (apt-get) for the browser tests of skinsynth view"; \
		(apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
		|| echo "warning: apt-get install chromium failed: the browser tests of skinsynth view will skip"; \
	else \
		echo "note: no chromium (as root: apt-get install chromium): the browser tests of skinsynth view will skip"; \
	fi

# The JavaScript clients the tests check glTF outputs with (Khronos glTF-Validator, three.js).
$(JS)/node_modules/.installed: $(JS)/package.json
	cd $(JS) && npm install --no-audit --no-fund --loglevel=error
	touch $@

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@

# Compile the numba loops and warp CPU kernels once, into the caches every later command loads
# (skinsynth precompile --help: where they are); again when their sources change.
$(VENV)/.precompiled: $(VENV)/.installed $(wildcard pipeline/skin/*.py pipeline/view/*.py gpu/kernels/*.py gpu/precompile.py)
	$(BIN)/skinsynth precompile
	touch $@

demo: setup
	@mkdir -p $(DEMO)
	$(BIN)/skinsynth example bending-bar -o $(DEMO)/bar.npz --frames 96 --cycles 2
	$(BIN)/skinsynth fit-skin $(DEMO)/bar.npz -o $(DEMO)/skin.h5 --bones 8 --seed 0
	$(BIN)/skinsynth inspect $(DEMO)/skin.h5
	$(BIN)/skinsynth export $(DEMO)/skin.h5 -o $(DEMO)/bar_skel.usda --as skel
	$(BIN)/skinsynth export $(DEMO)/skin.h5 -o $(DEMO)/bar_points.usdc --as points
	$(BIN)/skinsynth export $(DEMO)/skin.h5 -o $(DEMO)/bar_vat.exr
	$(BIN)/skinsynth export $(DEMO)/skin.h5 -o $(DEMO)/bar_vat/
	$(BIN)/skinsynth select-controls $(DEMO)/skin.h5 -o $(DEMO)/controls.h5
	$(BIN)/skinsynth train-kcca $(DEMO)/controls.h5 -o $(DEMO)/puppet.h5
	$(BIN)/skinsynth evaluate $(DEMO)/puppet.h5 --plot $(DEMO)/puppet_errors.png
	$(BIN)/skinsynth play $(DEMO)/puppet.h5 --controls $(DEMO)/bar.npz --instances 16 -o $(DEMO)/crowd.usdc
	$(BIN)/skinsynth build-graph $(DEMO)/skin.h5 -o $(DEMO)/graph.h5 --plot $(DEMO)/graph_plots
	$(BIN)/skinsynth synthesize $(DEMO)/graph.h5 -o $(DEMO)/bones.h5 --count 16 --frames 240 --seed 0 \
		--crowd $(DEMO)/synthesized_crowd.usdc
	$(BIN)/skinsynth preview $(DEMO)/bones.h5 -o $(DEMO)/synthesized.mp4 --animation 0 --animation 1
	$(BIN)/skinsynth preview $(DEMO)/puppet.h5 -o $(DEMO)/puppet_vs_truth.mp4
	@echo
	@echo "demo results in $(DEMO)/:"
	@echo "  skin.h5          fitted skin model (skinsynth inspect $(DEMO)/skin.h5)"
	@echo "  bar_skel.usda    UsdSkel rig + animation (open in usdview, Blender, Houdini, Maya)"
	@echo "  bar_points.usdc  baked point cache of the same animation"
	@echo "  bar_vat.exr      vertex-animation texture for game engines"
	@echo "  bar_vat/         engine-ready: offsets and normals textures, rest.obj/.glb with texel UVs, vat.json (docs/vat.md)"
	@echo "  controls.h5      8 control vertices chosen by PCA + varimax"
	@echo "  puppet.h5        kernel-CCA puppet driven by those controls"
	@echo "  puppet_errors.png held-out error of the puppet vs PCA blendshapes and RBF"
	@echo "  crowd.usdc       16 puppets played from the example's control points (UsdSkel, linear blend skinning)"
	@echo "  graph.h5         transitions, bone graph and splicing operators (plots in graph_plots/)"
	@echo "  bones.h5         16 new animations of 240 frames spliced from the example"
	@echo "  synthesized_crowd.usdc  those 16 animations on a grid (USD point caches): open it in a DCC"
	@echo "  synthesized.mp4  two of them rendered headless, seams marked red (skinsynth preview)"
	@echo "  puppet_vs_truth.mp4  the puppet's held-out frames next to the truth, its error in red"

# The manual (docs/, mkdocs.yml) built into build/site with --strict: a link to a missing page or
# anchor, or a page left out of the nav, fails it (never -q: mkdocs then drops the warnings that
# strict mode counts). Each command's --help on its page is checked by tests/contracts/test_docs.py.
docs: setup
	$(BIN)/mkdocs build --strict --site-dir build/site

# The suite on every core (pytest-xdist, -n auto: one worker per core; worksteal hands a finished
# worker the tests another has not started), the 10 slowest tests listed at the end. Each test also
# passes alone: python tests/run_each_file.py runs every test file in a process of its own.
PYTEST := $(BIN)/python -m pytest -q -n auto --dist worksteal --durations=10

test: setup docs blender-for-tests
	$(PYTEST)

test-fast: setup
	$(PYTEST) -m "not slow"

# Benchmarks print JSON lines; py-dem-bones is compared side by side when installed (pip install -e ".[bench]").
bench: setup
	$(BIN)/python benchmarks/fit_skin.py
	$(BIN)/python benchmarks/puppet.py
	$(BIN)/python benchmarks/graph.py
	$(BIN)/python benchmarks/play.py
	$(BIN)/python benchmarks/synthesize.py
	$(BIN)/python benchmarks/cluster.py
	$(BIN)/python benchmarks/lbs.py
	$(BIN)/python benchmarks/render.py
	$(BIN)/python benchmarks/cold_start.py
	$(BIN)/python benchmarks/markers.py

# Optional: Blender 5 as the bpy module (~370 MB) in a venv of its own, for tests/contracts/test_dcc_blender.py.
# bpy 5.0 wheels are built for Python 3.11 only; not part of setup.
BLENDER_VENV ?= .venv-blender
PYTHON311    ?= python3.11

blender: $(BLENDER_VENV)/.installed
	@echo
	@echo "Blender (bpy) is in $(BLENDER_VENV); run the Blender tests with:"
	@echo "  SKINSYNTH_BLENDER_PYTHON=$(BLENDER_VENV)/bin/python make test"

$(BLENDER_VENV)/.installed:
	$(PYTHON311) -m venv $(BLENDER_VENV)
	$(BLENDER_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(BLENDER_VENV)/bin/python -m pip install --quiet bpy==5.0.1
	$(BLENDER_VENV)/bin/python -c "import bpy; print('bpy', bpy.app.version_string)"
	touch $@

# The tests of .abc and .fbx reading (tests/formats/test_blender_caches.py) need Blender: bpy in its own
# venv, as `make blender`. Where it cannot be installed (no Python 3.11, no network) setup goes on and
# those tests skip, naming `make blender`.
blender-for-tests:
	@$(MAKE) --no-print-directory -s $(BLENDER_VENV)/.installed >/dev/null 2>&1 \
		|| echo "warning: Blender (bpy) could not be installed ($(PYTHON311), pip install bpy==5.0.1): the .abc/.fbx tests will skip"

clean:
	rm -rf build $(VENV) *.egg-info

# cagekit: the two commands of the README are `make demo` and `make test`.
# Both create (once) and reuse the virtual environment in .venv.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: package-check blender-venv test-blender blender-extension blender-render bench-blender demo test test-emulated test-slow lint docs architecture assets bench bench-assets bench-fit-cage bench-deform bench-learn bench-learn-real bench-learn-real-0ad game-assets bench-transfer bench-amplify models venv clean

$(STAMP): setup.cfg pyproject.toml constraints.txt constraints-common.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q -e '.[dev,learn,cluster]' -c constraints.txt
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/cagekit deform data/example/chair_source.obj data/example/chair_target.obj -o out/demo_deformed.obj --symmetry x --save-cage out/demo_cage.obj --preview out/demo.png
	@echo "wrote out/demo_deformed.obj, out/demo_cage.obj, out/demo_cage_deformed.obj and out/demo.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 tests

# The same tests as another CPU would run them: every library that picks its kernels by CPU is
# told to act as an older one (tests/cpu_kernels.py; the log's "cpu and kernels" part shows what
# each run used). Results differ in the last bits; the tests must not.
#   x86-64-v2: a Nehalem-class CPU, SSE4.2, no AVX (numba generic x86-64, numpy's baseline only,
#              OpenBLAS Nehalem, torch's default ATen kernels, MKL SSE4.2, oneDNN SSE4.1)
#   haswell:   AVX2 and FMA, no AVX-512 (numba haswell, numpy without X86_V4, OpenBLAS Haswell,
#              ATen AVX2, MKL AVX2, oneDNN AVX2)
# Elsewhere than x86-64 only numba is told (generic); numpy's and OpenBLAS's names are per machine.
ifeq ($(shell uname -m),x86_64)
EMULATIONS := x86-64-v2 haswell
CPU_x86-64-v2 := NUMBA_CPU_NAME=generic NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512_ICL AVX512_SPR" \
	OPENBLAS_CORETYPE=Nehalem ATEN_CPU_CAPABILITY=default MKL_ENABLE_INSTRUCTIONS=SSE4_2 ONEDNN_MAX_CPU_ISA=SSE41
CPU_haswell := NUMBA_CPU_NAME=haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \
	OPENBLAS_CORETYPE=Haswell ATEN_CPU_CAPABILITY=avx2 MKL_ENABLE_INSTRUCTIONS=AVX2 ONEDNN_MAX_CPU_ISA=AVX2
else
EMULATIONS := generic
CPU_generic := NUMBA_CPU_NAME=generic ATEN_CPU_CAPABILITY=default
endif
test-emulated: $(addprefix test-as-,$(EMULATIONS))

# one emulation: make test-as-haswell (or test-as-x86-64-v2)
test-as-%: $(STAMP)
	@echo '== the tests as a $* CPU would run them: $(CPU_$*)'
	env $(CPU_$*) $(BIN)/python -m pytest -q -n 2 -p no:cacheprovider tests

# The package as a user installs it: python -m build makes the sdist and the wheel; each is
# installed into a fresh venv beside older in-range versions of numpy, scipy, matplotlib and
# trimesh (which the installation must keep) and passes tests/package_smoke.py there.
PACKAGE_CHECK := out/package-check
OLDER := numpy==2.3.5 scipy==1.16.3 matplotlib==3.10.7 trimesh==4.12.2
SMOKE = cd $(PACKAGE_CHECK) && venv/bin/pip check && venv/bin/python $(CURDIR)/tests/package_smoke.py $(CURDIR)/data/example $(OLDER)
package-check: $(STAMP)
	rm -rf $(PACKAGE_CHECK)
	$(BIN)/python -m build -q --outdir $(PACKAGE_CHECK)/dist .
	$(PYTHON) -m venv $(PACKAGE_CHECK)/venv
	$(PACKAGE_CHECK)/venv/bin/pip install -q $(OLDER)
	$(PACKAGE_CHECK)/venv/bin/pip install -q $(PACKAGE_CHECK)/dist/cagekit-*.tar.gz
	$(SMOKE)
	$(PACKAGE_CHECK)/venv/bin/pip install -q --force-reinstall --no-deps $(PACKAGE_CHECK)/dist/cagekit-*.whl
	$(SMOKE)

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests

lint: $(STAMP)
	$(BIN)/ruff check cagekit cagekit_learn apps tests benchmarks data
	$(BIN)/mypy

# the API reference, built from the docstrings (Sphinx, numpydoc, autosummary over cagekit and
# cagekit_learn) with the README's library example run by sphinx-gallery: out/docs/index.html.
# Warnings are errors; the generated sources are written afresh each time.
docs: $(STAMP)
	$(BIN)/pip install -q -e '.[docs]' -c constraints.txt
	rm -rf docs/api/generated docs/api/gallery docs/api/sg_execution_times.rst
	$(BIN)/sphinx-build -W --keep-going -b html docs/api out/docs

# docs/architecture.md's module map, generated from the code (tests/test_layers.py checks it)
architecture: $(STAMP)
	$(BIN)/python tests/architecture.py

# Debian's sweethome3d-furniture (820 real models; installed as root when missing)
FURNITURE := /usr/share/sweethome3d/furniture/KatorLegaz.sh3f
assets:
	test -f $(FURNITURE) || DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends sweethome3d-furniture >/dev/null || (apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends sweethome3d-furniture >/dev/null)

# Debian's 0ad-data (1.4 GB: the game 0 A.D.'s 4,010 PMD meshes; installed as root when missing)
GAME_ART := /usr/share/games/0ad/mods/public/public.zip
game-assets:
	test -f $(GAME_ART) || DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends 0ad-data >/dev/null || (apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends 0ad-data >/dev/null)

# every model of sweethome3d-furniture loaded and caged (about 30 min on 2 cores)
bench-assets: $(STAMP) assets
	mkdir -p out
	$(BIN)/python benchmarks/bench_assets.py --json out/bench_assets.json --sheet out/assets_sheet.png

bench: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench]' -c constraints.txt
	$(BIN)/python benchmarks/bench_mvc.py

# needs Debian's libcgal-demo for its meshes (installed here when missing and run as root)
bench-fit-cage: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench]' -c constraints.txt
	test -f /usr/share/doc/libcgal-dev/data.tar.gz || apt-get install -y -q libcgal-demo
	$(BIN)/python benchmarks/bench_fit_cage.py

# needs libcgal-demo for the animal pairs (installed here when missing and run as root)
bench-deform: $(STAMP)
	test -f /usr/share/doc/libcgal-dev/data.tar.gz || apt-get install -y -q libcgal-demo
	$(BIN)/python benchmarks/bench_deform.py

# trains the learned cages for 20 minutes on 300 synthetic chairs, then compares on 50 pairs
bench-learn: $(STAMP)
	$(BIN)/python benchmarks/bench_learn.py --json out/bench_learn.json

# the shipped models (cagekit_learn/models/NAME.pt and NAME.json), trained from their recipes
# on sweethome3d-furniture (chairs: 3,000 steps, about 45 min on 2 cores; tables: its
# variations by amplify, 1 min, then 1,500 steps, about 25 min); commit both files
models: $(STAMP) assets
	$(BIN)/python -m cagekit_learn.make_shipped chairs
	$(BIN)/python -m cagekit_learn.make_shipped tables

# the shipped chairs model on unseen real seats, beside per-pair optimisation
bench-learn-real: $(STAMP) assets
	$(BIN)/python benchmarks/bench_learn_real.py --model chairs --json out/bench_learn_real.json --pictures out/learn_real

# the shipped models on the game furniture of 0ad-data (unseen low-poly tables and benches)
bench-learn-real-0ad: $(STAMP) assets game-assets
	$(BIN)/python benchmarks/bench_learn_real.py --recipe tables --model tables --test-set 0ad --json out/blr0ad/tables.json --pictures out/blr0ad/tables
	$(BIN)/python benchmarks/bench_learn_real.py --model chairs --test-set 0ad --json out/blr0ad/chairs.json --pictures out/blr0ad/chairs

# writes the humanoid data set (out/humanoid), trains the fixed-source model (6000 steps,
# about 16 min, reused when there) and compares the transfers with ground truth
bench-transfer: $(STAMP)
	$(BIN)/python benchmarks/bench_transfer.py --json out/bench_transfer.json --grid-dir out/transfer
	$(BIN)/python benchmarks/bench_character_cage.py --json out/bench_character_cage.json

# 40 variations of sweethome3d-furniture's chairs: 1 worker, 2 workers, a local Dask cluster
bench-amplify: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench,cluster]' -c constraints.txt
	$(BIN)/python benchmarks/bench_amplify.py --json out/bench_amplify.json --sheet docs/images/amplify_sheet.png

# Blender as a Python module (bpy 5.0.1, about 370 MB) in its own environment: Blender 5.0's
# Python has numpy 1.26.4, which the main environment's pins exclude (apps/blender)
BLENDER_VENV := .venv-blender
BLENDER_BIN := $(BLENDER_VENV)/bin
BLENDER_STAMP := $(BLENDER_VENV)/.installed
$(BLENDER_STAMP): setup.cfg pyproject.toml apps/blender/constraints.txt constraints-common.txt
	test -x $(BLENDER_BIN)/python || $(PYTHON) -m venv $(BLENDER_VENV)
	$(BLENDER_BIN)/pip install -q -e '.[dev,blender]' -c apps/blender/constraints.txt
	touch $(BLENDER_STAMP)

blender-venv: $(BLENDER_STAMP)

# the add-on's tests with the real bpy (marked blender; the default run skips them)
test-blender: $(BLENDER_STAMP)
	$(BLENDER_BIN)/python -m pytest -q -p no:cacheprovider -m blender tests/apps/test_blender.py

# the installable Blender extension (out/blender/cagekit-0.1.0-linux_x64.zip): the add-on with
# the wheels of cagekit and its dependencies for Blender 5.0's Python (downloaded from PyPI),
# then installed and run once in a throwaway Blender user folder
blender-extension: $(BLENDER_STAMP)
	$(BLENDER_BIN)/python apps/blender/build_extension.py --out out/blender --check

# the demo rendered in Blender (Cycles on the CPU, about 2 min on 2 cores): out/blender_demo.png
blender-render: $(BLENDER_STAMP)
	mkdir -p out
	$(BLENDER_BIN)/python apps/blender/render_demo.py --out out/blender_demo.png

# cagekit's live binding against Blender's Mesh Deform and Surface Deform, in one bpy run
bench-blender: $(BLENDER_STAMP)
	mkdir -p out
	$(BLENDER_BIN)/python benchmarks/bench_blender.py --json out/bench_blender.json

clean:
	rm -rf out .pytest_cache build *.egg-info docs/api/generated docs/api/gallery docs/api/sg_execution_times.rst

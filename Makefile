# cagekit: the two commands of the README are `make demo` and `make test`.
# Both create (once) and reuse the virtual environment in .venv.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-emulated test-slow lint assets bench bench-assets bench-fit-cage bench-deform bench-learn bench-transfer bench-amplify venv clean

$(STAMP): setup.cfg pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q -e '.[dev,learn,cluster]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/cagekit deform data/example/chair_source.obj data/example/chair_target.obj -o out/demo_deformed.obj --symmetry x --save-cage out/demo_cage.obj --preview out/demo.png
	@echo "wrote out/demo_deformed.obj, out/demo_cage.obj, out/demo_cage_deformed.obj and out/demo.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 tests

# the same tests as compiled for another CPU: numba for a generic x86-64 (no AVX2, no FMA)
# and numpy without its AVX2/AVX-512 kernels; results differ in the last bits, tests must not
EMULATED_CPU := NUMBA_CPU_NAME=generic
ifeq ($(shell uname -m),x86_64)
EMULATED_CPU += NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512_ICL AVX512_SPR"
endif
test-emulated: $(STAMP)
	$(EMULATED_CPU) $(BIN)/python -m pytest -q -n 2 -p no:cacheprovider tests

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests

lint: $(STAMP)
	$(BIN)/ruff check cagekit cagekit_learn apps tests benchmarks data

# Debian's sweethome3d-furniture (820 real models; installed as root when missing)
FURNITURE := /usr/share/sweethome3d/furniture/KatorLegaz.sh3f
assets:
	test -f $(FURNITURE) || DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends sweethome3d-furniture >/dev/null || (apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends sweethome3d-furniture >/dev/null)

# every model of sweethome3d-furniture loaded and caged (about 30 min on 2 cores)
bench-assets: $(STAMP) assets
	mkdir -p out
	$(BIN)/python benchmarks/bench_assets.py --json out/bench_assets.json --sheet out/assets_sheet.png

bench: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench]'
	$(BIN)/python benchmarks/bench_mvc.py

# needs Debian's libcgal-demo for its meshes (installed here when missing and run as root)
bench-fit-cage: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench]'
	test -f /usr/share/doc/libcgal-dev/data.tar.gz || apt-get install -y -q libcgal-demo
	$(BIN)/python benchmarks/bench_fit_cage.py

# needs libcgal-demo for the animal pairs (installed here when missing and run as root)
bench-deform: $(STAMP)
	test -f /usr/share/doc/libcgal-dev/data.tar.gz || apt-get install -y -q libcgal-demo
	$(BIN)/python benchmarks/bench_deform.py

# trains the learned cages for 20 minutes on 300 synthetic chairs, then compares on 50 pairs
bench-learn: $(STAMP)
	$(BIN)/python benchmarks/bench_learn.py --json out/bench_learn.json

# writes the humanoid data set (out/humanoid), trains the fixed-source model (6000 steps,
# about 16 min, reused when there) and compares the transfers with ground truth
bench-transfer: $(STAMP)
	$(BIN)/python benchmarks/bench_transfer.py --json out/bench_transfer.json --grid-dir out/transfer
	$(BIN)/python benchmarks/bench_character_cage.py --json out/bench_character_cage.json

# 40 variations of sweethome3d-furniture's chairs: 1 worker, 2 workers, a local Dask cluster
bench-amplify: $(STAMP)
	$(BIN)/pip install -q -e '.[dev,bench,cluster]'
	$(BIN)/python benchmarks/bench_amplify.py --json out/bench_amplify.json --sheet docs/images/amplify_sheet.png

clean:
	rm -rf out .pytest_cache build *.egg-info

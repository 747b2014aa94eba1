# cagekit: the two commands of the README are `make demo` and `make test`.
# Both create (once) and reuse the virtual environment in .venv.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow lint bench bench-fit-cage bench-deform bench-learn bench-transfer venv clean

$(STAMP): setup.cfg pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q -e '.[dev,learn]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/cagekit deform data/example/chair_source.obj data/example/chair_target.obj -o out/demo_deformed.obj --symmetry x --save-cage out/demo_cage.obj --preview out/demo.png
	@echo "wrote out/demo_deformed.obj, out/demo_cage.obj, out/demo_cage_deformed.obj and out/demo.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 tests

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests

lint: $(STAMP)
	$(BIN)/ruff check cagekit cagekit_learn apps tests benchmarks data

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
	$(BIN)/python benchmarks/bench_transfer.py --json out/bench_transfer.json --grid out/transfer_grid.png

clean:
	rm -rf out .pytest_cache build *.egg-info

# Two set-up commands (README): `make demo` and `make test`. Both install what they need.
PY      ?= python3
VENV    ?= .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
DEMO_OUT ?= out/demo

.PHONY: demo test sysdeps venv clean

sysdeps:
	@bash scripts/ensure_sysdeps.sh

$(STAMP): pyproject.toml | sysdeps
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch first, pinned to the local CPU build, so nothing else can pull a newer (CUDA) one.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e '.[test]'
	@touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/trumans sample --out $(DEMO_OUT)/demo --formats npz,bvh,glb,gif,png --json

test: $(STAMP)
	OMP_NUM_THREADS=2 $(BIN)/python -m pytest tests

clean:
	rm -rf out .pytest_cache

# The two commands of the README: `make demo` and `make test`.
# Both create ./.venv on first use and install the project with its dependencies.
PYTHON ?= python3
# One BLAS thread: the numeric core works on small matrices, where a threaded BLAS only costs
# (a 10x10 expm went from 37 µs to 4 ms on a loaded 2-core machine).
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/sim-plant demo

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/dpcontrol bench
	$(BIN)/sim-plant bench

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache

# The two commands of the README: `make demo` and `make test`.
# Both create ./.venv on first use and install the project with its dependencies.
# The interpreter ./.venv is made from: the distribution's /usr/bin/python3 when there is one (3.10 or newer),
# else python3 on PATH; `make PYTHON=/path/to/python3 ...` chooses another. Why the distribution's: it is what
# a vessel's systemd service runs on (README, "Installing on a vessel"), and distributions build CPython with
# profile-guided and link-time optimisation as a static interpreter: the lockstep benchmark ran 12-22 % faster
# on Debian's 3.11.2 than on a default source build beside it (pyenv's 3.11.7: shared libpython, no PGO).
# (`:=`, not `?=`: the probe runs once per make, not at every use of $(PYTHON))
ifeq ($(origin PYTHON),undefined)
PYTHON := $(shell /usr/bin/python3 -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null \
	&& echo /usr/bin/python3 || echo python3)
endif
# One BLAS thread: the numeric core works on small matrices, where a threaded BLAS only costs
# (a 10x10 expm went from 37 µs to 4 ms on a loaded 2-core machine).
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

# (remade when the Makefile changes too: it chooses the interpreter; --clear, as the old one may differ)
$(STAMP): pyproject.toml Makefile
	@echo "make: creating $(VENV) with $(PYTHON) ($$($(PYTHON) -c 'import sys; print(sys.version.split()[0])'))"
	$(PYTHON) -m venv --clear $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/sim-plant demo

test: $(STAMP)
	sh .ci/install-test-browser
	$(BIN)/ruff check .
	$(BIN)/python -m mypy
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m mypy

bench: $(STAMP)
	$(BIN)/dpcontrol bench
	$(BIN)/sim-plant bench

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache

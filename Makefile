# Two entry points on a fresh machine with only Python 3.11: `make run` and `make test`.
# Each creates .venv if missing and installs the package (editable, with the neural, cluster and test extras)
# at the exact versions of constraints.txt, CPU torch first so that nothing later can pull a CUDA build.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
# Extra pip arguments for torch, e.g. a CPU-only wheel index on a machine without a local CPU wheel.
TORCH_PIP_ARGS ?=

.PHONY: venv run test bench test-cmu test-fuzz test-browser clean-venv

$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet torch==2.13.0 $(TORCH_PIP_ARGS)
	$(PY) -m pip install --quiet -c constraints.txt -e '.[neural,cluster,test]'
	touch $(STAMP)

# The tests run one BLAS / OpenMP thread per process (unless the environment says otherwise): several test
# processes run at once (workers, subprocesses, CI's two lanes), and an idle OpenBLAS or OpenMP worker thread
# waits by spinning, taking the cycles another process needs (.ci/run says what it cost). The tests of a result
# that could depend on the thread count set the count themselves.
test test-cmu test-fuzz test-browser: export OPENBLAS_NUM_THREADS ?= 1
test test-cmu test-fuzz test-browser: export OMP_NUM_THREADS ?= 1
test test-cmu test-fuzz test-browser: export MKL_NUM_THREADS ?= 1

# The venv alone (.ci/run installs it while the runtime's C tests run).
venv: $(STAMP)

run: $(STAMP)
	$(PY) -m mocapbench.experiments.main

# PYTEST_FILES: test files or folders to run instead of all of them (.ci/run runs a few in its second lane).
test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_FILES)

test-cmu: $(STAMP)
	$(PY) -m pytest -q -m cmu

test-fuzz: $(STAMP)
	$(PY) -m pytest -q -m fuzz -s

# The report rendered in headless Chromium (needs `chromium`; .ci/run installs it when missing).
test-browser: $(STAMP)
	$(PY) -m pytest -q -m browser

bench: $(STAMP)
	$(PY) -m mocapbench.experiments.main --cmu

clean-venv:
	rm -rf $(VENV)

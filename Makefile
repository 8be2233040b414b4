# Two entry points on a fresh machine:
#   make demo   install, then run the main job on the embedded synthetic data
#   make test   install, then run the test suite
# torch is installed first, pinned to the local CPU build, so pip never resolves a CUDA build.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
TORCH_SPEC ?= torch==2.13.0
EXTRAS ?= dev,smplx,dask
DEMO_OUT ?= demo-out

.PHONY: install demo test bench clean

$(VENV)/.installed: setup.cfg pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install "$(TORCH_SPEC)"
	$(PIP) install -e ".[$(EXTRAS)]"
	touch $@

install: $(VENV)/.installed

demo: install
	$(VENV)/bin/hoibench demo --out $(DEMO_OUT)

test: install
	$(PY) -m pytest -q -n 2

bench: install
	$(PY) benchmarks/representations.py

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache

# Two entry points on a fresh machine:
#   make demo   install, then run the main job on the embedded synthetic data (~9 min on 2 idle cores)
#   make test   install, then run the test suite
# torch is installed first, pinned to the local CPU build, so pip never resolves a CUDA build.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
TORCH_SPEC ?= torch==2.13.0
EXTRAS ?= dev,smplx,dask,physics,fast
DEMO_OUT ?= demo-out

.PHONY: install demo test bench clean check-system

check-system:
	@ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0' || { \
	  echo "hoibench needs the system library libusb-1.0-0 (used by open3d). Install it (Debian/Ubuntu):"; \
	  echo "  as root:       apt-get install libusb-1.0-0"; \
	  echo "  otherwise:     sudo apt-get install libusb-1.0-0"; exit 1; }

$(VENV)/.installed: setup.cfg pyproject.toml | check-system
	@echo "[install 1/4] virtual environment in $(VENV)"
	$(PYTHON) -m venv $(VENV)
	@echo "[install 2/4] pip"
	$(PIP) install -q --upgrade pip
	@echo "[install 3/4] $(TORCH_SPEC), CPU build (~0.8 GB; the longest step)"
	$(PIP) install -q "$(TORCH_SPEC)"
	@echo "[install 4/4] hoibench and its dependencies [$(EXTRAS)] (open3d-cpu, pyvista/VTK, pymeshlab, transformers)"
	$(PIP) install -q -e ".[$(EXTRAS)]"
	@du -sh $(VENV) 2>/dev/null | sed 's/^/[install] done: environment size /' || true
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

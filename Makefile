# rgbd_rs developer entry points. `make help` lists them.
# The virtualenv and the cargo target dir live outside the clone (keyed by pyproject's hash via a
# stamp file), so a fresh clone on a machine that already built once starts in seconds.
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help

CACHE ?= $(HOME)/.cache/rgbd_rs
VENV ?= $(CACHE)/venv
PY := $(VENV)/bin/python
export CARGO_TARGET_DIR ?= $(CACHE)/target
export PYO3_PYTHON := $(PY)
DEPS_STAMP := $(VENV)/.deps-$(shell sha256sum pyproject.toml tools/deps.py | sha256sum | cut -c1-16)
PYDIRS := python tests benches tools

.PHONY: help env build demo test lint fmt rust-test py-test docs docs-serve wheel bench clean

help: ## list the targets
	@grep -hE '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-10s %s\n", $$1, $$2}'

env: $(DEPS_STAMP) ## create/update the cached virtualenv ($(VENV))

$(DEPS_STAMP):
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) tools/deps.py | xargs $(PY) -m pip install -q
	@rm -f $(VENV)/.deps-* && touch $@

build: env ## build the native extension (release) into the virtualenv
	VIRTUAL_ENV=$(VENV) PATH=$(VENV)/bin:$$PATH $(VENV)/bin/maturin develop --release -q 2>&1 | sed "/already satisfied/d"

demo: build ## run the demo (`rgbd demo`)
	$(VENV)/bin/rgbd demo --out out/demo

lint: build ## rustfmt, clippy -D warnings, ruff, mypy, stubtest
	cargo fmt --all --check
	cargo clippy --workspace --all-targets -q -- -D warnings
	$(VENV)/bin/ruff check $(PYDIRS)
	$(VENV)/bin/ruff format --check $(PYDIRS)
	$(VENV)/bin/mypy
	$(PY) -m mypy.stubtest rgbd_rs._rgbd_rs

fmt: env ## format Rust and Python in place
	cargo fmt --all
	$(VENV)/bin/ruff format $(PYDIRS)
	$(VENV)/bin/ruff check --fix $(PYDIRS)

rust-test: ## cargo test --workspace (and build the benches)
	cargo test --workspace -q
	cargo bench --workspace --no-run -q

py-test: build ## pytest
	$(PY) -m pytest -q

docs: build ## build the docs site into site/ (strict: a broken link or reference fails)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict -q

docs-serve: build ## serve the docs site with live reload on http://127.0.0.1:8000
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve

test: lint rust-test py-test docs ## everything CI runs: lint, cargo tests, pytest, the docs build

wheel: env ## build the wheel, install it into a fresh venv, smoke-test it there
	rm -rf $(CACHE)/dist $(CACHE)/wheel-venv
	$(VENV)/bin/maturin build --release -q -o $(CACHE)/dist
	python3 -m venv $(CACHE)/wheel-venv
	# The fresh venv borrows the dependencies (torch is GBs) but not the editable rgbd_rs.
	$(PY) -c "import site; print(site.getsitepackages()[0])" > \
	  $$($(CACHE)/wheel-venv/bin/python -c "import site; print(site.getsitepackages()[0])")/deps.pth
	$(CACHE)/wheel-venv/bin/python -m pip install -q --no-deps $(CACHE)/dist/*.whl
	cd /tmp && $(CACHE)/wheel-venv/bin/rgbd --help > /dev/null
	cd /tmp && $(CACHE)/wheel-venv/bin/python -c "import rgbd_rs, pathlib; \
	  p = pathlib.Path(rgbd_rs.__file__); assert 'wheel-venv' in str(p), p; \
	  assert (p.parent / 'py.typed').exists(); \
	  assert (p.parent / 'nn' / 'weights' / 'confidence.pt').stat().st_size > 1000; \
	  assert (p.parent / 'nn' / 'weights' / 'shapes_modelnet10.pt').stat().st_size > 1000; \
	  assert (p.parent / 'nn' / 'weights' / 'shapes_modelnet40.pt').stat().st_size > 1000; \
	  assert (p.parent / 'nn' / 'weights' / 'semantic_nyuv2.pt').stat().st_size > 1000; \
	  from rgbd_rs.meshes import box; from rgbd_rs.shapes import classify; \
	  print('classify a box:', classify(box((1.0, 0.6, 0.4)))[0]); \
	  import numpy as np; cam = rgbd_rs.PinholeCamera(100., 100., 10., 10., 20, 20); \
	  print('wheel OK:', p.parent, cam.project(np.array([[0., 0., 1.]])))"

bench: build ## run the benchmarks (criterion + Python vs OpenCV, scipy, trimesh/embree, Open3D)
	$(PY) tools/deps.py --only bench | xargs $(PY) -m pip install -q
	cargo bench -p rgbd-geom -p rgbd-spline -p rgbd-render -p rgbd-fusion
	$(PY) benches/bench_geom.py
	$(PY) benches/bench_spline.py
	$(PY) benches/bench_render.py
	$(PY) benches/bench_fusion.py
	cd benches && $(PY) bench_hha.py && $(PY) bench_oversegment.py --threads 2 && \
	  $(PY) bench_merge.py && $(PY) bench_views.py --markdown && $(PY) bench_voxels.py

clean: ## remove build outputs (keeps the cached venv)
	cargo clean
	rm -rf out site python/rgbd_rs/*.so

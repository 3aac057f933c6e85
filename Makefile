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

env: $(DEPS_STAMP) ## create/update the cached virtualenv (~/.cache/rgbd_rs/venv unless VENV= says)

$(DEPS_STAMP):
	@echo "rgbd_rs: installing the Python dependencies into $(VENV) (torch included: several minutes the first time)"
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) tools/deps.py | xargs $(PY) -m pip install -q
	@rm -f $(VENV)/.deps-* && touch $@

build: env ## build the native extension (release) into the virtualenv
	@# PIP_QUIET: maturin's pip install of the requirements shows warnings and errors only, not
	@# "Ignoring <an extra's requirement>: markers don't match" for every extra not installed.
	@echo "rgbd_rs: building the Rust extension (release; about 5 minutes the first time on 2 cores, seconds after)"
	VIRTUAL_ENV=$(VENV) PATH=$(VENV)/bin:$$PATH PIP_QUIET=1 $(VENV)/bin/maturin develop --release -q

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

wheel: env ## build the wheel, check its imports against its declared deps, smoke-test it alone
	rm -rf $(CACHE)/dist $(CACHE)/wheel-venv
	$(VENV)/bin/maturin build --release -q -o $(CACHE)/dist
	$(PY) -m venv $(CACHE)/wheel-venv
	# Every import of the wheel's code is declared in its Requires-Dist, no declared pin excludes
	# the tested versions; then the fresh venv gets links to the installed closure of the core
	# requirements only (what `pip install` gives a user, without downloading torch again).
	$(PY) tools/check_wheel_deps.py $(CACHE)/dist/*.whl --link-into \
	  $$($(CACHE)/wheel-venv/bin/python -c "import sysconfig; print(sysconfig.get_path('purelib'))")
	$(CACHE)/wheel-venv/bin/python -m pip install -q --no-deps --no-index $(CACHE)/dist/*.whl
	$(CACHE)/wheel-venv/bin/python -m pip check
	cd /tmp && $(CACHE)/wheel-venv/bin/rgbd --help > /dev/null
	cd /tmp && $(CACHE)/wheel-venv/bin/python -I $(CURDIR)/tools/wheel_smoke.py --expect-in wheel-venv

bench: build ## run the benchmarks (criterion + Python vs OpenCV, scipy, trimesh/embree, Open3D)
	$(PY) tools/deps.py --only bench | xargs $(PY) -m pip install -q
	cargo bench -p rgbd-geom -p rgbd-spline -p rgbd-render -p rgbd-fusion
	$(PY) benches/bench_geom.py
	$(PY) benches/bench_spline.py
	$(PY) benches/bench_render.py
	$(PY) benches/bench_fusion.py
	$(PY) benches/bench_stereo.py
	cd benches && $(PY) bench_hha.py && $(PY) bench_oversegment.py --threads 2 && \
	  $(PY) bench_merge.py && $(PY) bench_views.py --markdown && $(PY) bench_voxels.py && \
	  $(PY) bench_curvature.py && $(PY) bench_segment.py

clean: ## remove build outputs (keeps the cached venv)
	cargo clean
	rm -rf out site python/rgbd_rs/*.so

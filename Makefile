# flow_node: `make demo` runs the product on the bundled bag, `make test` lints and runs the tests.
# Everything installs into .venv from requirements.txt (no system ROS needed).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba_cache

.PHONY: all venv test lint demo fuzz bench bench-quick bench-accuracy bench-node bench-batch bench-venv paper clean test-noble noble-venv

all: test

$(STAMP): requirements.txt setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e .
	touch $(STAMP)

venv: $(STAMP)

lint: $(STAMP)
	$(VENV)/bin/ruff check flow_node test bench

test: lint
	$(PY) -m pytest -q test

demo: $(STAMP)
	$(PY) -m flow_node.demo

# The property-based fuzz tests at 20x their make-test example count, then the live-node campaign over DDS
# (bench/fuzz_node.py; results in bench/results/node/fuzz_node.json, BENCHMARKS.md).
fuzz: $(STAMP)
	FLOW_FUZZ_SCALE=20 $(PY) -m pytest -q test/test_fuzz.py
	$(PY) -m bench.fuzz_node

# Benchmarks need peers (opencv-contrib DualTVL1, scikit-image) that conflict with the runtime's
# opencv-python-headless, so they get their own venv.
BENCH_VENV := .venv-bench
BENCH_STAMP := $(BENCH_VENV)/.installed
$(BENCH_STAMP): bench/requirements.txt requirements.txt setup.py
	test -x $(BENCH_VENV)/bin/python || $(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/pip install --quiet --upgrade pip
	$(BENCH_VENV)/bin/pip install --quiet -r bench/requirements.txt
	$(BENCH_VENV)/bin/pip install --quiet --no-deps -e .
	touch $(BENCH_STAMP)

bench-venv: $(BENCH_STAMP)

# The broad accuracy suite (issue 11): every preset and the peers on every regime, one run (~20-30 min);
# writes bench/results/suite/suite.{json,md,png} and the generated summary in BENCHMARKS.md.
bench: $(BENCH_STAMP)
	nice $(BENCH_VENV)/bin/python -m bench.suite --update-benchmarks

bench-quick: $(BENCH_STAMP)
	$(BENCH_VENV)/bin/python -m bench.suite --quick

# Middlebury only: every model with quality's schedule (issue 2; presets and peers: the suite's middlebury regime);
# bench/results/accuracy/accuracy.{json,md}. Choosing the model brings its calibrated weights (config.MODEL_WEIGHTS).
MODELS := l2_l2 l2_tv l1_tv l1_tv_l2 l1_tv_tv
bench-accuracy: $(BENCH_STAMP)
	$(BENCH_VENV)/bin/python -m bench.suite --regimes middlebury --peers none \
		$(foreach m,$(MODELS),--method $(m)=quality,model=$(m)) --out bench/results/accuracy/accuracy.json

# The live node over DDS (issues 4, 13; ~5 min, nothing else running): latency and in-node overhead per preset
# and size with the package's Fast DDS profile in both processes, then delivery of ~/flow to another process per
# middleware setting (bench.node, one mode each); bench/results/node/node_latency.json, node_delivery.json.
bench-node: $(STAMP)
	FASTRTPS_DEFAULT_PROFILES_FILE=$(CURDIR)/config/fastdds_localhost.xml \
		$(PY) -m bench.node latency --frames 20 --presets fastest realtime quality
	$(PY) -m bench.node delivery --seconds 10 --repeats 2

# Batch evaluation on Dask against a plain loop, 1 and 2 workers (issue 14; ~8 min on a quiet machine);
# bench/results/batch/batch.json.
bench-batch: $(STAMP)
	$(PY) -m bench.batch --size 160x120:24 --variants loop,dask-1,dask-2 --repeats 6

paper: $(BENCH_STAMP)
	$(BENCH_VENV)/bin/python -m bench.paper

# Ubuntu 24.04's library versions (python 3.12, numpy 1.26, OpenCV 4.6, numba 0.61): the same suite in a
# second venv (.ci/noble-requirements.txt). NOBLE_PYTHON: a python3.12 on PATH, else pyenv's.
NOBLE_VENV := .venv-noble
NOBLE_STAMP := $(NOBLE_VENV)/.installed
NOBLE_PYTHON ?= $(shell for p in python3.12 $(HOME)/.pyenv/versions/3.12*/bin/python3.12; do \
		$$p -c '' 2>/dev/null && { command -v $$p; break; }; done)
$(NOBLE_STAMP): .ci/noble-requirements.txt requirements-system-ros.txt setup.py
	@test -n "$(NOBLE_PYTHON)" || { echo "test-noble: no python3.12 found (set NOBLE_PYTHON=...)"; exit 1; }
	test -x $(NOBLE_VENV)/bin/python || $(NOBLE_PYTHON) -m venv $(NOBLE_VENV)
	$(NOBLE_VENV)/bin/pip install --quiet --upgrade pip
	$(NOBLE_VENV)/bin/pip install --quiet -r .ci/noble-requirements.txt
	$(NOBLE_VENV)/bin/pip install --quiet --no-deps -e .
	touch $(NOBLE_STAMP)

noble-venv: $(NOBLE_STAMP)

test-noble: $(NOBLE_STAMP)
	NUMBA_CACHE_DIR=$(CURDIR)/$(NOBLE_VENV)/numba_cache $(NOBLE_VENV)/bin/python -m pytest -q test

clean:
	rm -rf $(VENV) $(BENCH_VENV) $(NOBLE_VENV) build install log *.egg-info

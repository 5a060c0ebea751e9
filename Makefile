# roomseg-bench: `make help` lists the targets.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
# torch/torchvision are pinned to builds that install offline on the project's machines.
TORCH_PIN ?= torch==2.14.1 torchvision==0.29.1

.PHONY: help setup setup-core test lint bench perf tables figures clean

help:  ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-10s %s\n", $$1, $$2}'

setup: $(VENV)/.installed  ## create .venv; install the package, test tools, models (torch) and thor (ai2thor) extras

$(VENV)/.installed: pyproject.toml
	python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q $(TORCH_PIN)
	$(PIP) install -q -e ".[dev,models,thor]"
	touch $@

setup-core: ## create .venv with the core only (no torch): everything but the image classifiers
	python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e ".[dev]"

test: setup  ## run the test suite
	$(PY) -m pytest -q

lint: setup  ## ruff
	$(VENV)/bin/ruff check benchmark envs tests

# make bench: the offline benchmark (sizes: BENCH_HOUSES houses per dataset).
comma := ,
SHARED ?= ../shared/data
BENCH_HOUSES ?= 20
BENCH_ENVS := synthetic$(if $(wildcard $(SHARED)/procthor/*.jsonl.gz),$(comma)procthor_shared,)
BENCH_OUT ?= results/bench

bench: setup  ## offline benchmark (no GPU): sweep -> results/runs/bench, tables + figures -> results/bench
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench experiment=bench env=$(BENCH_ENVS) run.limit=$(BENCH_HOUSES)
	$(PY) -m benchmark.commands.tables results/runs/bench --out $(BENCH_OUT) --table table3 --table table4 --table all
	$(PY) -m benchmark.commands.figures from-run results/runs/bench --out $(BENCH_OUT)/figures

perf:  setup ## time aggregators and post-processing against their references (prints ratios, memory)
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.perf

tables: setup  ## paper tables from every run under results/runs -> results/tables
	$(PY) -m benchmark.commands.tables results/runs --out results/tables

clean:  ## remove caches (keeps .venv and results/)
	rm -rf .pytest_cache .ruff_cache .hypothesis build *.egg-info

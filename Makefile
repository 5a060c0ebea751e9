# roomseg-bench: `make help` lists the targets.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
# torch/torchvision are pinned to builds that install offline on the project's machines.
TORCH_PIN ?= torch==2.14.1 torchvision==0.29.1

.PHONY: help setup setup-test setup-docs setup-gpu test test-fast lint bench bench-publish perf sensitivity sensitivity-publish tables figures report readme-tables gpu-check docs robustness robustness-publish robustness-timing-publish rose2-env ipa-env leaderboard scaling scaling-publish scaling-10k-publish perf-publish segment-memory-publish compile-publish install-sizes-publish docs-numbers clean

help:  ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-14s %s\n", $$1, $$2}'

# Two steps: `setup` is what the offline bench and the core need (no torch, no simulators, no
# transformers); `setup-test` adds what the whole test suite needs on top (torch pinned, the
# models and thor extras, pytest and ruff). `make test` runs it first, so CI runs every test.
setup: $(VENV)/.installed  ## create .venv with the core (offline bench, tables, figures, report, ROS bags)

# rosbags (the `bags` extra: pure Python, small) comes with the core, so that a robot user's first
# `roomseg-segment bag=...` works from `make setup` (the extra's name is not on PyPI)
$(VENV)/.installed: pyproject.toml
	python3 -m venv $(VENV)
	$(PIP) install -q -e ".[bags]"
	@# numba's kernels compiled once here, into its cache, so no run waits for them (docs/sweeps-and-clusters.md)
	$(PY) -m benchmark.commands.compile_kernels
	touch $@

setup-test: $(VENV)/.installed-test  ## add what the tests need: torch, transformers, ai2thor, pytest, ruff

$(VENV)/.installed-test: $(VENV)/.installed
	$(PIP) install -q $(TORCH_PIN)
	$(PIP) install -q -e ".[test]"
	touch $@

setup-gpu: setup-test  ## GPU workstation: add the gpu extra (bitsandbytes, the VLM's 4-bit quantisation) to .venv (docs/gpu.md)
	$(PIP) install -q -e ".[gpu]"

test: setup-test  ## run the whole test suite (what CI runs)
	$(PY) -m pytest -q

test-fast: setup-test  ## the developer loop: tests not marked slow, 2 processes; fails a test over 2 s not marked slow
	$(PY) -m pytest -q -m "not slow" -n 2 --max-unmarked-seconds 2

lint: setup-test  ## ruff
	$(VENV)/bin/ruff check benchmark envs tests

# make bench: the offline benchmark (sizes: BENCH_HOUSES houses per dataset).
comma := ,
SHARED ?= ../shared/data
BENCH_HOUSES ?= 20
BENCH_ENVS := synthetic$(if $(wildcard $(SHARED)/procthor/*.jsonl.gz),$(comma)procthor_shared,)
BENCH_OUT ?= results/bench
# where runs and caches go (run.results_dir); bench-publish uses a fresh one
RESULTS ?= results

bench: setup  ## offline benchmark (no GPU): sweep -> results/runs/bench; tables, figures, report.html -> results/bench
	@$(if $(findstring procthor_shared,$(BENCH_ENVS)),,echo "make bench: the shared ProcTHOR houses are absent ($(SHARED)/procthor): generated houses only; get them with: $(PY) -m benchmark.commands.data fetch procthor_shared --root $(SHARED)" >&2)
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench experiment=bench env=$(BENCH_ENVS) run.limit=$(BENCH_HOUSES) run.results_dir=$(RESULTS)
	@# the figures, and the tables then the report, read the finished run side by side; any failing fails bench.
	@# Ctrl-C (or make killed) stops the figures too: a background job of this shell ignores SIGINT
	$(PY) -m benchmark.commands.figures from-run $(RESULTS)/runs/bench --last-sweep --out $(BENCH_OUT)/figures & fig=$$!; \
	trap 'kill $$fig 2>/dev/null; wait $$fig 2>/dev/null; exit 130' INT TERM HUP; \
	$(PY) -m benchmark.commands.tables $(RESULTS)/runs/bench --last-sweep --out $(BENCH_OUT) --table table3 --table table4 --table all \
	  && $(PY) -m benchmark.commands.report $(RESULTS)/runs/bench --last-sweep --out $(BENCH_OUT)/report.html; rep=$$?; \
	wait $$fig && exit $$rep

report: setup  ## a sweep as one HTML page: RUN=results/runs/<name> (default bench) -> RUN's folder/report.html
	$(PY) -m benchmark.commands.report $(or $(RUN),$(RESULTS)/runs/bench) --out $(or $(RUN),$(RESULTS)/runs/bench)/report.html

# README numbers: bench-publish times `make bench` BENCH_TIMING_RUNS times as on a fresh clone
# and copies the first run's per-house metrics to results/published/bench (committed);
# readme-tables writes the README's generated blocks from results/published (tests/test_readme_tables.py checks them).
PUBLISH_TMP := results/.publish
# a numba cache that starts empty, as on a fresh clone (the published timings are taken with it)
FRESH_NUMBA = NUMBA_CACHE_DIR=$(abspath $(PUBLISH_TMP))/numba-cache
BENCH_TIMING_RUNS ?= 5
bench-publish: setup  ## `make bench` timed BENCH_TIMING_RUNS (5) times as on a fresh clone, empty and filled cache; metrics -> results/published/bench (then: make readme-tables)
	rm -rf $(PUBLISH_TMP) && mkdir -p $(PUBLISH_TMP)
	@# each run as on a fresh clone: numba's cache empty, then filled by make setup's compile step (timed
	@# apart), then make bench into an empty results folder and again into the same one (its cache filled);
	@# per run GNU time's wall seconds and peak RSS, and /proc/loadavg as it ended -> PUBLISH_TMP/timing/<run>/
	for i in $$(seq $(BENCH_TIMING_RUNS)); do \
	  t=$(PUBLISH_TMP)/timing/$$i r=$(PUBLISH_TMP)/run-$$i; mkdir -p $$t; \
	  export NUMBA_CACHE_DIR=$(abspath $(PUBLISH_TMP))/numba-cache-$$i; \
	  /usr/bin/time -f '%e %M' -o $$t/compile.txt $(PY) -m benchmark.commands.compile_kernels || exit 1; \
	  for c in empty filled; do \
	    /usr/bin/time -f '%e %M' -o $$t/$$c.txt $(MAKE) --no-print-directory bench RESULTS=$$r BENCH_OUT=$$r/bench || exit 1; \
	    cat /proc/loadavg > $$t/$$c.load; \
	  done; \
	  if [ $$i -gt 1 ]; then rm -rf $$r $$NUMBA_CACHE_DIR; fi; \
	done
	$(PY) -m benchmark.commands.maintainer.readme_tables publish $(PUBLISH_TMP)/run-1/runs/bench --name bench --timings $(PUBLISH_TMP)/timing

robustness-publish: setup  ## fresh timed `make robustness`, its rows -> results/published/robustness, where its time went -> results/published/robustness_profile.md (then: make readme-tables)
	rm -rf $(PUBLISH_TMP) && mkdir -p $(PUBLISH_TMP)
	$(FRESH_NUMBA) /usr/bin/time -f '%e %M' -o $(PUBLISH_TMP)/compile-time.txt $(PY) -m benchmark.commands.compile_kernels
	$(FRESH_NUMBA) /usr/bin/time -f '%e %M' -o $(PUBLISH_TMP)/time.txt $(MAKE) --no-print-directory robustness RESULTS=$(PUBLISH_TMP) ROBUST_OUT=$(PUBLISH_TMP)/robustness
	$(PY) -m benchmark.commands.maintainer.readme_tables publish $(PUBLISH_TMP)/runs/robustness --name robustness --time $(PUBLISH_TMP)/time.txt --compile-time $(PUBLISH_TMP)/compile-time.txt --command "make robustness" --columns robustness
	$(PY) -m benchmark.commands.maintainer.grid_profile $(PUBLISH_TMP)/runs/robustness --out results/published/robustness_profile.md

# the grid at the size target of the robustness claims' houses (100 a dataset), timed as on a fresh
# clone -> results/published/robustness_timing.md (its time, then where it went); its rows are not published
ROBUST_TIMING_HOUSES ?= 100
robustness-timing-publish: setup  ## fresh timed `make robustness ROBUST_HOUSES=100 ROBUST_IPA=0` (the fresh-clone grid: no ipa rows), then its sweep again on the cache it filled (the jobs' fixed cost) -> results/published/robustness_timing.md (time and profile)
	rm -rf $(PUBLISH_TMP) && mkdir -p $(PUBLISH_TMP)
	$(FRESH_NUMBA) /usr/bin/time -f '%e %M' -o $(PUBLISH_TMP)/compile-time.txt $(PY) -m benchmark.commands.compile_kernels
	$(FRESH_NUMBA) /usr/bin/time -f '%e %M' -o $(PUBLISH_TMP)/time.txt $(MAKE) --no-print-directory robustness ROBUST_HOUSES=$(ROBUST_TIMING_HOUSES) ROBUST_IPA=0 RESULTS=$(PUBLISH_TMP) ROBUST_OUT=$(PUBLISH_TMP)/robustness
	$(FRESH_NUMBA) /usr/bin/time -f '%e %M %U %S' -o $(PUBLISH_TMP)/rerun-time.txt env $(ROBUST_SWEEP) run.limit=$(ROBUST_TIMING_HOUSES) run.results_dir=$(PUBLISH_TMP)/rerun run.cache_dir=$(PUBLISH_TMP)/cache
	$(PY) -m benchmark.commands.maintainer.grid_profile $(PUBLISH_TMP)/runs/robustness --time $(PUBLISH_TMP)/time.txt --compile-time $(PUBLISH_TMP)/compile-time.txt --rerun-time $(PUBLISH_TMP)/rerun-time.txt --command "make robustness ROBUST_HOUSES=$(ROBUST_TIMING_HOUSES) ROBUST_IPA=0" --out results/published/robustness_timing.md

# make leaderboard: every method on the same maps (shared ProcTHOR houses from 75, after the
# objects_procthor classifier's training houses): view-based methods, geometric segmenters,
# sanity rows, and ROSE² with ROSE2=<checkout>; the Table V-style table -> results/leaderboard.
LEADER_HOUSES ?= 20
leaderboard: setup  ## Table V-style leaderboard on the shared ProcTHOR maps (ROSE2=<checkout> adds ROSE², make ipa-env the ipa rows) -> results/leaderboard
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench experiment=leaderboard run.limit=$(LEADER_HOUSES) run.results_dir=$(RESULTS)
	$(if $(ROSE2),ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench env=procthor_shared env.start=75 segmenter=rose2 segmenter.checkout=$(ROSE2) run.name=leaderboard run.limit=$(LEADER_HOUSES) run.results_dir=$(RESULTS) hydra.run.dir=$(RESULTS)/runs/leaderboard/rose2 run.allow_failures=true,@echo "ROSE2 not set: no ROSE² row (make rose2-env, then make leaderboard ROSE2=<checkout>)")
	$(if $(wildcard $(IPA_ENV)/bin/ipa_segment),for s in $(IPA_SEGMENTERS); do ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench env=procthor_shared env.start=75 segmenter=$$s segmenter.env_dir=$(abspath $(IPA_ENV)) run.name=leaderboard run.limit=$(LEADER_HOUSES) run.results_dir=$(RESULTS) hydra.run.dir=$(RESULTS)/runs/leaderboard/$$s run.allow_failures=true || exit 1; done,@echo "no ipa_room_segmentation build in $(IPA_ENV): no ipa rows (make ipa-env)")
	$(PY) -m benchmark.commands.tables $(RESULTS)/runs/leaderboard --table table5 --out results/leaderboard

# ROSE² (segmenter=rose2) runs from your own checkout in an isolated environment with the
# versions it needs: its requirements.txt as they install today on Python 3.11 (shapely < 2 for
# cascaded_union and multi-geometry iteration, NumPy < 2 for that shapely, OpenCV < 5); the
# project's driver handles the rest (benchmark/segmenters/rose2_driver.py, docs/baselines.md).
ROSE2 ?= $(ROOMSEG_ROSE2)
ROSE2_VENV ?= .venv-rose2
ROSE2_PIN ?= numpy==1.26.4 shapely==1.8.5.post1 opencv-python-headless==4.11.0.86 scikit-learn==1.9.1 \
	scikit-image==0.26.0 scipy==1.17.1 skan==0.13.1 networkx==3.6.1 matplotlib Pillow descartes tabulate pypng numba==0.68.1
rose2-env:  ## ROSE²'s isolated environment in .venv-rose2 (then: segmenter=rose2 with ROSE2=<checkout> or ROOMSEG_ROSE2)
	python3 -m venv $(ROSE2_VENV)
	$(ROSE2_VENV)/bin/pip install -q $(ROSE2_PIN)
	@echo "ROSE2 environment ready in $(ROSE2_VENV); point segmenter.checkout (or ROOMSEG_ROSE2) at your ROSE2 checkout$(if $(ROSE2), ($(ROSE2)),)"

# ipa_room_segmentation (segmenter=ipa_morphological, ipa_distance, ipa_voronoi, ipa_semantic,
# ipa_vrf): the authors' C++ (ipa320/ipa_coverage_planning at IPA_COMMIT) built without ROS into
# one driver, $(IPA_ENV)/bin/ipa_segment (native/ipa/, docs/baselines.md). IPA_SRC: your checkout
# or clone of it (a folder or git repository); unset: git clone IPA_URL (needs the network).
# OpenGM (header-only, VRF only) likewise from OPENGM_SRC or OPENGM_URL at OPENGM_COMMIT; the
# other four build without it when IPA_VRF=0. IPA_VRF_FIX=1: the VRF's AdaBoost features as the
# authors' OpenCV 2 code computed them (native/ipa/roomseg_weak_responses.h; 0: as published,
# whose OpenCV 4 branch reads uninitialised memory there). Debian packages: cmake g++ libopencv-dev
# libboost-filesystem-dev libdlib-dev. Nothing fetched is committed: $(IPA_ENV) is git-ignored.
IPA_ENV ?= .ipa-env
IPA_URL ?= https://github.com/ipa320/ipa_coverage_planning.git
IPA_COMMIT ?= f8a1dae4a09693f36a84fd92b6f9772d4c6faff1
OPENGM_URL ?= https://github.com/opengm/opengm.git
OPENGM_COMMIT ?= decdacf4caad223b0ab5478d38a855f8767a394f
IPA_VRF ?= 1
IPA_VRF_FIX ?= 1
IPA_JOBS ?= 2
IPA_SEGMENTERS ?= ipa_morphological ipa_distance ipa_voronoi ipa_semantic ipa_vrf
ipa-env:  ## ipa_room_segmentation's five algorithms built without ROS into .ipa-env/bin/ipa_segment (IPA_SRC=<checkout>, OPENGM_SRC=<checkout>)
	@set -e; env=$(abspath $(IPA_ENV)); mkdir -p $$env/bin; \
	fetch() { src="$$1"; url="$$2"; commit="$$3"; dest="$$4"; \
	  if [ -n "$$src" ] && ! git -C "$$src" rev-parse --git-dir >/dev/null 2>&1; then \
	    [ -d "$$src" ] || { echo "$$5=$$src: no such folder" >&2; exit 2; }; echo "$$(cd "$$src" && pwd)"; return; fi; \
	  if [ ! -d "$$dest" ]; then git clone -q --no-checkout "$${src:-$$url}" "$$dest" >&2; fi; \
	  git -C "$$dest" checkout -q "$$commit" >&2 || { echo "$$5: commit $$commit not in $${src:-$$url}" >&2; exit 2; }; echo "$$dest"; }; \
	ipa=$$(fetch "$(IPA_SRC)" "$(IPA_URL)" "$(IPA_COMMIT)" "$$env/ipa_coverage_planning" IPA_SRC); \
	opengm=; if [ "$(IPA_VRF)" = 1 ]; then opengm=$$(fetch "$(OPENGM_SRC)" "$(OPENGM_URL)" "$(OPENGM_COMMIT)" "$$env/opengm" OPENGM_SRC)/include; fi; \
	cmake -S native/ipa -B $$env/build -DIPA_SRC="$$ipa" -DOPENGM_INCLUDE="$$opengm" -DIPA_VRF_FIX=$(if $(filter 1,$(IPA_VRF_FIX)),ON,OFF) >/dev/null; \
	cmake --build $$env/build -j $(IPA_JOBS); \
	cp $$env/build/ipa_segment $$env/bin/ipa_segment; \
	commit=$$(git -C "$$ipa" rev-parse HEAD 2>/dev/null || echo unknown); \
	printf '{"ipa_src": "%s", "ipa_commit": "%s", "vrf": %s, "vrf_fix": %s}\n' "$$ipa" "$$commit" "$$( [ -n "$$opengm" ] && echo true || echo false)" "$(if $(filter 1,$(IPA_VRF_FIX)),true,false)" > $$env/build.json; \
	echo "ipa_room_segmentation built: $$env/bin/ipa_segment (ipa_coverage_planning $$commit$$( [ -n "$$opengm" ] || echo ', without VRF'))"

readme-tables: setup  ## rewrite the README's generated results blocks from results/published/
	$(PY) -m benchmark.commands.maintainer.readme_tables write

scaling: setup  ## houses/s, wall, CPU, peak memory, ms per stage: 100 and 1,000 generated houses on 1 and 2 workers
	$(PY) -m benchmark.commands.maintainer.scaling --houses 100 1000 --workers 1 2

scaling-publish: setup  ## make scaling's table -> results/published/scaling.md (included by docs/sweeps-and-clusters.md)
	@# the runs' results and caches on the disk of results/, as bench-publish's (not the system's temporary folder)
	rm -rf $(PUBLISH_TMP)/scaling
	$(PY) -m benchmark.commands.maintainer.scaling --houses 100 1000 --workers 1 2 --work $(PUBLISH_TMP)/scaling --out results/published/scaling.md
	rm -rf $(PUBLISH_TMP)/scaling

scaling-10k-publish: setup  ## one configuration over 10,000 generated houses (ProcTHOR-10k's size) on 2 workers, several minutes -> results/published/scaling_10k.md (docs/sweeps-and-clusters.md)
	rm -rf $(PUBLISH_TMP)/scaling
	$(PY) -m benchmark.commands.maintainer.scaling --houses 10000 --workers 2 --work $(PUBLISH_TMP)/scaling --out results/published/scaling_10k.md
	rm -rf $(PUBLISH_TMP)/scaling

# roomseg-segment's peak memory on N x N rooms of 10 m (20 40: 4020^2 and 8020^2 px, 1.5 GB), extrapolated to 16000^2 px;
# measured there with `make perf PERF_SEGMENT_ROOMS="20 40 80"` (80: 16020^2 px, ~2 minutes more, 5.5 GB of memory)
PERF_SEGMENT_ROOMS ?= 20 40
perf:  setup ## time aggregators and post-processing against their references (prints ratios, memory)
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.maintainer.perf --segment-rooms $(PERF_SEGMENT_ROOMS)

perf-publish: setup  ## make perf's tables -> results/published/perf.md (included by docs/robot-conditions.md)
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.maintainer.perf --robot-houses 10 --out results/published/perf.md

# Measurements (timings and sizes: not re-made by a test, each file's first line says when, where
# and by which command it was measured); the docs pages include them as they are.
segment-memory-publish: setup  ## roomseg-segment's peak memory and time on 8020^2 and 16020^2 px maps (~2 min, 5.5 GB) -> results/published/segment_memory.md (docs/own-robot-data.md)
	$(PY) -m benchmark.commands.maintainer.perf --houses 0 --synthetic 0 --robot-houses 0 --segment-rooms 40 80 --out results/published/segment_memory.md

compile-publish: setup  ## the numba warm-up timed with an empty and a filled cache -> results/published/compile_kernels.md (docs/sweeps-and-clusters.md)
	$(PY) -m benchmark.commands.compile_kernels --measure --out results/published/compile_kernels.md

install-sizes-publish: setup-test  ## .venv's size by install step (core, docs, test extras, torch, CUDA) -> results/published/install_sizes.md (docs/getting-started.md)
	$(PY) -m benchmark.commands.maintainer.install_sizes --out results/published/install_sizes.md

# the numbers the docs pages include (tests/test_docs_numbers.py runs each command again and
# fails when it writes other numbers); the measured ones (timings, memory, sizes) are written by
# the *-publish targets: perf, scaling, scaling-10k, segment-memory, compile, install-sizes, bench, robustness,
# robustness-timing
docs-numbers: setup  ## the numbers the docs include -> results/published/: autotrace coverage, the default confusion matrix, robot coverage, SLAM levels, map calibration, the scanner fitted to real logs, house statistics, clutter tables, tables examples, SeLRoS Table V, leaderboard, objects accuracy, sensitivity (ROSE2=<checkout> adds ROSE²)
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.robot_coverage --n 20 --out results/published/robot_coverage.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.coverage --range 0:150 --out results/published/coverage.md
	$(PY) -m benchmark.commands.view_confusion --markdown results/published/oracle_confusion.md classifier=objects env.seed_start=1000 env.n_houses=50 run.progress=false
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.maintainer.slam_levels --n 10 --out results/published/slam_levels.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.map_stats --calibrate --n 5 --out results/published/map_calibration.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.calibrate --houses 5 --out results/published/calibration.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.house_stats --synthetic 500 --out results/published/house_stats.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.clutter_tables --offices 7 --houses 40 --out results/published/clutter_tables.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.tables_examples --small 2 --large 3 --houses 4 --out results/published/tables_examples.md
	ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_ROSE2=$(ROSE2) $(PY) -m benchmark.commands.selros --markdown results/published/selros_table5.md
	$(if $(wildcard $(IPA_ENV)/bin/ipa_segment),ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_IPA_ENV=$(abspath $(IPA_ENV)) ROOMSEG_ROSE2= $(PY) -m benchmark.commands.selros --ipa --no-sanity --markdown results/published/selros_table5_ipa.md,@echo "no ipa_room_segmentation build in $(IPA_ENV): results/published/selros_table5_ipa.md not rewritten (make ipa-env)")
	$(if $(wildcard $(IPA_ENV)/bin/ipa_segment),ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_IPA_ENV=$(abspath $(IPA_ENV)) $(PY) -m benchmark.commands.ipa_ports --markdown results/published/ipa_ports.md,@echo "no ipa_room_segmentation build in $(IPA_ENV): results/published/ipa_ports.md not rewritten (make ipa-env)")
	$(if $(wildcard $(IPA_ENV)/bin/ipa_segment),ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_IPA_ENV=$(abspath $(IPA_ENV)) $(PY) -m benchmark.commands.maintainer.vrf_causes --markdown results/published/vrf_causes.md,@echo "no ipa_room_segmentation build in $(IPA_ENV): results/published/vrf_causes.md not rewritten (make ipa-env)")
	ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_ROSE2=$(ROSE2) $(PY) -m benchmark.commands.maintainer.sweep_table experiment=leaderboard run.limit=5 --rose2-with env=procthor_shared --rose2-with env.start=75 --table table5 --out results/published/leaderboard.md
	ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.objects_accuracy --train 0:75 --train generated:100000:100200 --eval 75:150 --out results/published/objects_accuracy.md
	$(PY) -m benchmark.commands.maintainer.sweep_table experiment=sensitivity env=synthetic run.limit=5 --table sensitivity --out results/published/sensitivity.md

# On a GPU workstation: the active environment's python (conda, README) unless .venv exists.
GPU_PY ?= $(if $(wildcard $(PY)),$(PY),python3)

gpu-check:  ## GPU workstation, first step: CUDA, AI2-THOR render, Habitat, real classifier weights, 1-house run (pass/FAIL/skipped table)
	$(GPU_PY) -m benchmark.commands.maintainer.gpu_check

# make robustness: every method under the robot conditions of conf/corruption (6 families x 5
# severities, explore_0, lost 1-3, kidnap 1-2, clean) on ROBUST_HOUSES houses per dataset; tables
# and figures -> ROBUST_OUT. 200: what the power report of a 20-house run asked to detect 3 points
# of matched IoU at 80 % power at the median paired spread ("How many houses" in robustness.md);
# ProcTHOR stops at its 150 shared houses. A house that fails under a condition (a SLAM estimate
# that diverges off the map) is recorded with its reason; the tables name it and leave it out of
# its dataset's cells, so the sweep goes on to the tables (run.allow_failures=true).
ROBUST_HOUSES ?= 200
ROBUST_OUT ?= results/robustness
# the generated houses at that size (env=synthetic holds 20), beside the shared ProcTHOR houses
ROBUST_ENVS := $(subst synthetic,synthetic_robust,$(BENCH_ENVS))
# the ipa rows (make ipa-env built .ipa-env/bin/ipa_segment): the authors' five algorithms, a second
# multirun into runs/robustness/ipa (conf/experiment/robustness_ipa.yaml: clean and scan, slam,
# explore, realistic at severities 1, 3, 5) on the first ROBUST_IPA_HOUSES houses per dataset, on
# the main sweep's maps (no more than ROBUST_HOUSES); the tables show them apart beside the ports
# on those houses. 1: about 10 minutes on the 2-core machine (its VRF and semantic segmentations
# are nearly all of it; docs/robustness.md), each house more about as long again.
# ROBUST_IPA=0: none (robustness-timing-publish: the fresh-clone grid).
ROBUST_IPA_HOUSES ?= 1
ROBUST_IPA ?= 1
# the robustness sweep (its houses and folders follow): `make robustness`, and its rerun on a filled cache in robustness-timing-publish
ROBUST_SWEEP = ROOMSEG_SHARED_DATA=$(SHARED) $(PY) -m benchmark.commands.bench experiment=robustness env=$(ROBUST_ENVS) run.allow_failures=true
robustness: setup  ## robustness benchmark: methods x robot conditions x severities -> results/runs/robustness; tables, figures -> results/robustness
	$(ROBUST_SWEEP) run.limit=$(ROBUST_HOUSES) run.results_dir=$(RESULTS)
	$(if $(filter 0,$(ROBUST_IPA)),@echo "ROBUST_IPA=0: no ipa rows (the fresh-clone grid)",$(if $(wildcard $(IPA_ENV)/bin/ipa_segment),ROOMSEG_SHARED_DATA=$(SHARED) ROOMSEG_IPA_ENV=$(abspath $(IPA_ENV)) $(PY) -m benchmark.commands.bench experiment=robustness_ipa env=$(ROBUST_ENVS) run.limit=$$(( $(ROBUST_IPA_HOUSES) < $(ROBUST_HOUSES) ? $(ROBUST_IPA_HOUSES) : $(ROBUST_HOUSES) )) run.results_dir=$(RESULTS) run.allow_failures=true,@echo "no ipa_room_segmentation build in $(IPA_ENV): no ipa rows (make ipa-env)"))
	$(PY) -m benchmark.commands.robustness $(RESULTS)/runs/robustness --last-sweep --out $(ROBUST_OUT)

sensitivity: setup  ## oracle noise models x accuracy x aggregator x post on 20 generated houses -> results/sensitivity
	$(PY) -m benchmark.commands.bench experiment=sensitivity env=synthetic run.limit=20
	$(PY) -m benchmark.commands.tables results/runs/sensitivity --last-sweep --table sensitivity --out results/sensitivity

sensitivity-publish: sensitivity  ## make sensitivity, then its plots -> docs/figures (the docs' copies, tracked)
	mkdir -p docs/figures && cp results/sensitivity/sensitivity*.png docs/figures/

tables: setup  ## paper tables from every run under results/runs -> results/tables
	$(PY) -m benchmark.commands.tables results/runs --out results/tables

# make docs needs the core and MkDocs only (no torch: every command's --help runs without it)
setup-docs: $(VENV)/.installed-docs  ## add MkDocs (the docs extra) to the core .venv, no torch

$(VENV)/.installed-docs: $(VENV)/.installed
	$(PIP) install -q -e ".[docs]"
	touch $@

docs: setup-docs  ## the docs site: generated reference pages (commands, config) + MkDocs build, strict -> site/ (no torch needed)
	$(PY) -m benchmark.commands.maintainer.docs reference
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:  ## remove caches (keeps .venv and results/)
	rm -rf .pytest_cache .ruff_cache .hypothesis build *.egg-info

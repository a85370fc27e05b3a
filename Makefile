# Two entry points: `make run` (the main job) and `make test` (the whole suite).
# Each creates .venv and installs what it needs on first use.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test test-fast test-stress lint browser bench results docs mutate clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	# setuptools prints a notice on every editable install of a mapped layout
	# (folders named like the package could shadow it; none is named formation_swarm).
	# rl: the learning adapters' tests run PettingZoo's and Gymnasium's own checkers.
	# ros2: the ROS 2 topics, their bridge and `swarm export --mcap` (rosbags, no ROS).
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip install --quiet -e '.[dev,bench,rl,ros2]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/swarm run fig11_obstacles

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python tools/lint_imports.py
	$(BIN)/ruff format --check .

# The suite's files on TEST_JOBS workers (pytest-xdist; a file's tests share a worker,
# so its module fixtures run once); TEST_JOBS=0 runs it in this one process. Three on
# two cores: most tests wait on real time (570 s here against 731 s with two).
TEST_JOBS ?= 3
test: lint browser
	$(BIN)/python -m pytest -n $(TEST_JOBS) --dist loadfile --no-loadscope-reorder

# The tier to run while changing code: tests/unit and tests/packaging (no test there
# starts a run's processes), less those marked slow; it prints its own wall time.
test-fast: $(STAMP)
	@start=$$(date +%s); $(BIN)/ruff check . && $(BIN)/ruff format --check --quiet . && \
	$(BIN)/python -m pytest -q -n $(TEST_JOBS) -m "not slow" --durations=5 tests/unit tests/packaging; \
	status=$$?; echo "make test-fast: $$(($$(date +%s) - start)) s"; exit $$status

# The suite beside two CPU hogs (tools/stress.sh): its retries and time bounds
# must hold on a busy machine. PYTEST_ARGS="tests/system" runs a part of it.
PYTEST_ARGS ?=
test-stress: lint browser
	sh tools/stress.sh $(BIN)/python -n $(TEST_JOBS) --dist loadfile --no-loadscope-reorder $(PYTEST_ARGS)

# The web viewer's test (tests/system/test_web_view.py) loads it in a headless Chromium:
# installed here when missing and this is root on apt; otherwise the test skips, saying why.
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	{ [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
	  echo "installing chromium for the web viewer's test (apt-get)" && \
	  { DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y -q chromium >/dev/null 2>&1 || \
	    { timeout 300 apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y -q chromium >/dev/null 2>&1; }; } || \
	  echo "no chromium: the web viewer's test will skip (apt-get install -y chromium)"; }

bench: $(STAMP)
	$(BIN)/python bench/fuzzy_step.py
	$(BIN)/python bench/lockstep.py
	$(BIN)/python bench/realtime.py
	$(BIN)/python bench/start.py

# The generated tables and figures of docs/results.md: the baseline (180 lockstep
# runs, one process per robot), the same under wheel noise (180); then, stepped in
# one process (the lockstep runs' very rows, in minutes), the paper's claims over
# 30 seeds as shipped (with the rows tests/system/test_claims.py checks against
# its lockstep runs, and the avoidance's ablation), under wheel noise, with the
# EKF told it (3 x 240), the claims at every value of one setting at a time (10
# seeds per value: 2,720 runs beyond the claims' own, which it shares; their rows,
# and the lists of where each claim holds and of the rank swap, written from
# them), the claims as margins with intervals, the EKF's NEES and the avoidance's
# study (1,410 runs); resumable: an interrupted `make results` goes on where it
# stopped.
NOISE_SET := --set robot.wheel_noise_mps=0.1
EKF_TOLD := --set controller.ekf.q_pos_m=0.13 --set controller.ekf.q_phi_rad=0.09
results: $(STAMP)
	$(BIN)/swarm results --seeds 10 --write docs/results.md --write README.md
	$(BIN)/swarm results --seeds 10 $(NOISE_SET) --write docs/results.md
	$(BIN)/swarm results --claims --seeds 30 --rows docs/results/claims.csv --write docs/results.md
	$(BIN)/swarm results --claims --seeds 30 $(NOISE_SET) --write docs/results.md
	$(BIN)/swarm results --claims --seeds 30 $(NOISE_SET) $(EKF_TOLD) --write docs/results.md
	$(BIN)/swarm results --sensitivity --seeds 10 --rows docs/results/sensitivity.csv --write docs/results.md
	$(BIN)/python -m formation_swarm.studies.margins --seeds 30 --rows docs/results/margins.csv --write docs/results.md

# Reference documents generated from the code (a test fails when one is stale).
docs: $(STAMP)
	$(BIN)/python -m formation_swarm.spec.keys_doc > docs/scenario.md
	$(BIN)/python -m formation_swarm.common.faults.doc docs/faults.md

# Mutation testing of the pure modules against their fast tests (tools/mutate.py):
# a fixed sample of 120 mutants per module (about an hour and a half here), resumable
# (sessions in .mutation/), not part of `make test`. MUTATE_ARGS= runs them all;
# MUTATE_ARGS="--fresh agents/ekf.py" one module from scratch.
MUTATE_ARGS ?= --sample 120
$(VENV)/.mutate-installed: $(STAMP)
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip install --quiet -e '.[dev,bench,rl,mutate]'
	touch $@

mutate: $(VENV)/.mutate-installed
	$(BIN)/python tools/mutate.py --list-survivors $(MUTATE_ARGS)

clean:
	rm -rf $(VENV) build *.egg-info .mutation

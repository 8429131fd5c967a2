# Two entry points do all set-up: `make demo` and `make test` (see README); `make docs` builds
# the documentation site.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo live ros2-demo test lint bench docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test,docs]'
	touch $(STAMP)

RECORDING := examples/traffic/recording
SPEEDING := forall c in Car: always (Speed[c] > 60 -> eventually[0, 300] Speed[c] <= 60)

# The traffic example (thesis 1.2): platform 2's data reveals car2's violation (exit status 1).
demo: $(STAMP) $(RECORDING)/metadata.yaml
	$(BIN)/dkreason match --config examples/federation.toml "$(SPEEDING)"
	$(BIN)/dkreason monitor --config examples/federation.toml --source $(RECORDING) --delay 0.1 \
	    --plot examples/traffic/monitor.png "$(SPEEDING)" || test $$? -eq 1

# The same example live: three platform nodes replay their parts in step (30x), a monitor
# on platform 1 finds them over Zenoh on loopback (port 7447).
live: $(STAMP) $(RECORDING)/metadata.yaml
	@origin=$$($(BIN)/python -c 'import time; print(time.time() + 5)'); pids=; \
	for n in 1 2 3; do $(BIN)/dkreason serve --config examples/live/platform$$n.toml \
	    --connect tcp/127.0.0.1:7447 --source $(RECORDING) --origin $$origin --speed 30 \
	    > /dev/null & pids="$$pids $$!"; done; \
	$(BIN)/dkreason monitor --live --config examples/live/monitor.toml \
	    --listen tcp/127.0.0.1:7447 --delay 0.1 --until 330 "$(SPEEDING)" \
	    "always (Position[car2] >= 0)"; status=$$?; kill $$pids; test $$status -eq 1

# The same example as three live ROS 2 robots (rmw_zenoh's wire format, no ROS install): the
# replay announces its publishers and /clock, `monitor --ros2 --sim-time` finds them on
# loopback (port 7448), subscribes to the relevant topics only and finds car2's violation.
MSGS := $(foreach m,$(wildcard examples/traffic/msg/dkreason_msgs/msg/*.msg),--msg $(m))
ros2-demo: $(STAMP) $(RECORDING)/metadata.yaml
	@$(BIN)/python examples/ros2/replay.py $(RECORDING) --listen tcp/127.0.0.1:7448 \
	    --speed 30 --delay 3 & pid=$$!; \
	$(BIN)/dkreason monitor --ros2 --sim-time --config examples/federation.toml $(MSGS) \
	    --connect tcp/127.0.0.1:7448 --delay 0.5 --until 330 --record examples/ros2/run.mcap \
	    "$(SPEEDING)" "always (Position[car2] >= 0)"; status=$$?; kill $$pid 2>/dev/null; \
	test $$status -eq 1

$(RECORDING)/metadata.yaml: examples/traffic/simulate.py $(STAMP)
	rm -rf $(RECORDING)
	$(BIN)/python examples/traffic/simulate.py $(RECORDING)

# Both cores (pytest-xdist): the suite stays under five minutes on a 2-core machine.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

lint: $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[lint]'
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[bench]'
	$(BIN)/python -m benchmarks.bench_cli
	$(BIN)/python -m benchmarks.bench_match
	$(BIN)/python -m benchmarks.bench_monitor
	$(BIN)/python -m benchmarks.bench_progress
	$(BIN)/python -m benchmarks.bench_live
	$(BIN)/python -m benchmarks.bench_ros2
	$(BIN)/python -m benchmarks.bench_join
	$(BIN)/python -m benchmarks.chapter7 --growth
	$(BIN)/python -m benchmarks.chapter7 --sorts
	$(BIN)/python -m benchmarks.bench_fleet
	$(BIN)/python -m benchmarks.bench_owlrl
	$(BIN)/python -m benchmarks.bench_owl_memory
	$(BIN)/python -m benchmarks.bench_adapt

# The documentation site (mkdocs.yml, pages in docs/) into site/; --strict: a broken link or
# API reference is an error, as in the test that builds it.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

clean:
	rm -rf $(VENV) build site src/*.egg-info

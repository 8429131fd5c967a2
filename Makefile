# Two entry points do all set-up: `make demo` and `make test` (see README).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/dkreason match --config examples/federation.toml \
	    "forall x in UAV, y in Car: always (Altitude[x] > 10 and Speed[x] > Speed[y])"
	$(BIN)/dkreason specs list --config examples/federation.toml

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check '.[bench]'
	$(BIN)/python -m benchmarks.bench_match
	$(BIN)/python -m benchmarks.bench_progress

clean:
	rm -rf $(VENV) build src/*.egg-info

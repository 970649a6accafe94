# Two commands do everything on a fresh Debian machine with Python 3.11:
#   make demo   -- create .venv, install, run the main job
#   make test   -- create .venv, install (and Foxglove's bag readers, npm), run the tests
#   make view   -- open the latest demo's Rerun recording (make view-web: in the browser, no GPU needed)
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo view view-web pictures test test-slow bench install clean

$(STAMP): requirements.txt setup.py setup.cfg
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	$(BIN)/python -m pip install --quiet --no-deps -e .
	@touch $(STAMP)

# Foxglove's bag readers for the tests (npm, pinned by the lock file), on the node of requirements.txt
FOXGLOVE := tests/foxglove/package.json tests/foxglove/package-lock.json
FOXGLOVE_STAMP := $(VENV)/foxglove/.installed

$(FOXGLOVE_STAMP): $(STAMP) $(FOXGLOVE)
	@mkdir -p $(VENV)/foxglove && cp $(FOXGLOVE) $(VENV)/foxglove/
	$(BIN)/npm ci --prefix $(VENV)/foxglove --silent --no-audit --no-fund
	@touch $(FOXGLOVE_STAMP)

install: $(STAMP) $(FOXGLOVE_STAMP)

DEMO_RRD := out/demo/latest/twin.rrd

demo: $(STAMP)
	$(BIN)/kilobot-twin demo --out out/demo

view: $(STAMP)
	@test -f $(DEMO_RRD) || { echo "no $(DEMO_RRD) yet: run make demo first"; exit 2; }
	$(BIN)/rerun $(DEMO_RRD)

view-web: $(STAMP)
	@test -f $(DEMO_RRD) || { echo "no $(DEMO_RRD) yet: run make demo first"; exit 2; }
	$(BIN)/rerun --web-viewer $(DEMO_RRD)

pictures: $(STAMP)
	sh docs/make_pictures.sh

test: $(STAMP) $(FOXGLOVE_STAMP)
	$(BIN)/python -m pytest -q -n auto --dist worksteal

test-slow: $(STAMP) $(FOXGLOVE_STAMP)
	$(BIN)/python -m pytest -q -n auto -m slow

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_batch.py

clean:
	rm -rf $(VENV) out build install log *.egg-info

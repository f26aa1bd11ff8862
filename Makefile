# Two commands: `make run` and `make test`. Both build .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test bench lint screenshots clean-venv system-deps

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip setuptools wheel
	# torch first and pinned: the local CPU build, never the CUDA one from the registry
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e ".[test]"
	touch $(STAMP)

# Debian packages Qt needs at run time (QtMultimedia links libpulse). Root on this kind of machine.
system-deps:
	@missing=""; for p in libpulse0 libegl1 libxkbcommon0 libfontconfig1 libdbus-1-3 libgl1; do \
	  dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO="sudo"; \
	  echo "installing Debian packages:$$missing"; \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; fi

run: $(STAMP)
	$(BIN)/tactile-studio gui

# one pytest-xdist worker per core (at most 4): about half the suite waits on real time,
# processes and pipes, so two workers on two cores take ~45% less wall time
TEST_WORKERS ?= auto
test: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --maxprocesses 4

lint: $(STAMP)
	$(BIN)/ruff check tactile_studio ui plugins tests benchmarks tools
	# the import contracts and the cycle check over core, ui and plugins together
	$(BIN)/python tools/house_imports.py
	# mypy --strict on the public seams; Any, mypy errors, long and wide functions never rise
	$(BIN)/python tools/house_ratchet.py

# Regenerates every picture in docs/screenshots (and the protocol pictograms) offscreen.
screenshots: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python tools/make_protocol_images.py
	for f in tools/screenshots/make_*.py; do \
	  echo "$$f"; QT_QPA_PLATFORM=offscreen $(BIN)/python "$$f" || exit 1; done
	TACTILE_STUDIO_SCREENSHOTS=docs/screenshots QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q \
	  tests/test_ui_research.py tests/test_ui_research_train.py tests/test_ui_research_recipe.py \
	  tests/test_ui_live_inference.py tests/test_ui_personalise.py tests/test_ui_xdf.py \
	  tests/test_ui_check_flags.py tests/test_ui_player_trials.py tests/test_session_identity.py \
	  tests/test_ui_research_shots.py

bench: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m benchmarks

clean-venv:
	rm -rf $(VENV)

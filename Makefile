# Two commands do everything on a fresh Debian/Ubuntu machine:
#   make demo   the paper's D-bar experiment end to end, with logs and plots
#   make test   every test: lint, Python tests, firmware native tests, AVR build, firmware in the loop
# Both set up what they need (Debian packages, .venv) once; a second run reinstalls nothing.
# make demo installs the package with its runtime dependencies only; make test adds the test, bench
# and live extras (pyproject.toml) beside it.

PYTHON  ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
RUNTIME := $(VENV)/.runtime-stamp
EXTRAS  := $(VENV)/.test-extras-stamp
DEBS    := build/.debs-stamp
DEMODEBS := build/.debs-demo-stamp

.PHONY: demo test lint pytest firmware setup clean

demo: $(DEMODEBS) $(RUNTIME)
	$(BIN)/gyrotens demo

test: setup lint firmware pytest

setup: $(DEBS) $(EXTRAS)

$(DEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh all
	@mkdir -p build && touch $@

$(DEMODEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh demo
	@mkdir -p build && touch $@

$(RUNTIME): pyproject.toml setup.py model/gyrotensegrity/_fastkernel.c
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e .
	@touch $@

$(EXTRAS): $(RUNTIME) tools/extras.py
	$(BIN)/pip install -q $$($(BIN)/python tools/extras.py test bench live)
	@touch $@

lint:
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	find firmware -path firmware/build -prune -o \
	    \( -name '*.cpp' -o -name '*.h' -o -name '*.c' \) -print0 | \
	    xargs -0 -r clang-format --dry-run -Werror

firmware:
	$(MAKE) -C firmware check

pytest:
	$(BIN)/pytest

clean:
	rm -rf build firmware/build out

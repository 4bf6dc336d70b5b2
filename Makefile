# Two commands do everything on a fresh Debian/Ubuntu machine:
#   make demo   the paper's D-bar experiment end to end, with logs and plots
#   make test   every test: lint, Python tests, firmware native tests, AVR build, firmware in the loop
# Both set up what they need (Debian packages, .venv) once; a second run reinstalls nothing.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
DEBS   := build/.debs-stamp

.PHONY: demo test lint pytest firmware setup clean

demo: setup
	$(BIN)/gyrotens demo

test: setup lint firmware pytest

setup: $(DEBS) $(STAMP)

$(DEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh
	@mkdir -p build && touch $@

$(STAMP): pyproject.toml setup.py model/gyrotensegrity/_fastkernel.c
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev,bench]'
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

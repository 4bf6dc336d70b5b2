# Two commands do everything on a fresh Debian/Ubuntu machine:
#   make demo   the paper's D-bar experiment end to end, with logs and plots
#   make test   every test: lint, Python tests, firmware native tests, AVR build, firmware in the loop
#   make lab    a lab laptop: gyrotens with its runtime and what flashing needs (AVR toolchain,
#               avrdude), nothing of the test suite's
#   make flash PORT=/dev/ttyACM0   the wheel-board firmware (the ELF the FIL tests run) onto the Mega,
#                                  once its brown-out fuse is checked (tools/check-bod.sh)
#   make study NAME=estimator [ARGS=...]   a study or group of studies/ into reports/NAME.md
#   make oldest [PYTHON_OLDEST=python3.10]   the package with its dependency floors on the oldest
#               supported Python found (tools/oldest-python.sh), and the tests that only compute
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
LABDEBS := build/.debs-lab-stamp

.PHONY: demo lab oldest floors test lint pytest pytest-computing pytest-beside-rig pytest-fil pytest-rig \
        studies-check \
        study firmware setup clean flash

# The Mega 2560's bootloader speaks STK500v2 at 115200 baud; opening the port resets the board into
# it. -D: the bootloader cannot erase the chip, it rewrites the pages it is given.
PROGRAMMER   ?= stk500v2
FIRMWARE_ELF := firmware/build/avr/wheelboard.elf

demo: $(DEMODEBS) $(RUNTIME)
	$(BIN)/gyrotens demo

lab: $(LABDEBS) $(RUNTIME)

# The floors of pyproject.toml (tools/oldest-constraints.txt) on Python 3.10, in a venv of its own;
# the package installed, not editable, so the tests import what a user gets.
PYTHON_OLDEST ?= $(shell tools/oldest-python.sh)
OLDEST        := build/venv-oldest
OLDEST_TESTS  := tests/model tests/host tests/control tests/estimator tests/test_wheelproto.py \
                 tests/test_wheelboard.py tests/test_cli.py tests/test_errors.py
oldest: $(DEMODEBS)
	@test -n "$(PYTHON_OLDEST)" || { echo "make oldest PYTHON_OLDEST=/path/to/python3.10" >&2; exit 2; }
	test -x $(OLDEST)/bin/python || $(PYTHON_OLDEST) -m venv $(OLDEST)
	$(OLDEST)/bin/pip install -q -c tools/oldest-constraints.txt . pytest hypothesis
	$(OLDEST)/bin/python -m pytest -q -p no:cacheprovider -m "not real_time and not slow" \
	    --ignore tests/model/test_rig_fidelity_mujoco.py $(OLDEST_TESTS)

# The firmware builds and runs its native tests (one core, half a minute) beside the computing
# tests, then the floors check (floors below) takes its place; the firmware-in-the-loop tests,
# then the slow computing ones, beside the simulated rig's: see pytest below.
test: setup lint studies-check
	$(MAKE) --no-print-directory -j2 --output-sync=target firmware pytest-computing floors
	$(MAKE) --no-print-directory -j2 --output-sync=target pytest-beside-rig pytest-rig

# The floors as a user installs them on the oldest Python found (or PYTHON_OLDEST), and one
# simulation from outside the checkout (tools/check-floors.sh): about a minute, half of it
# download; its 20-25 s of CPU, shared with the computing tests' two workers, add about half that
# to their stage (reports/portability.md). Not beside the real-time tests: a rig run needs most
# of the machine (tests/conftest.py).
floors:
	tools/check-floors.sh

setup: $(DEBS) $(EXTRAS)

$(DEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh all
	@mkdir -p build && touch $@

$(DEMODEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh demo
	@mkdir -p build && touch $@

$(LABDEBS): tools/ensure-debs.sh
	tools/ensure-debs.sh lab
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

# The suite fuzzes the frame decoder for 50,000 inputs (a few seconds); make -C firmware fuzz
# runs its default 200,000.
firmware:
	$(MAKE) -C firmware check FUZZ_RUNS=50000

# The computing tests on two workers, then the real-time ones (tests/conftest.py): those of the
# simulated rig one after the other (a run needs most of a core: rig, loop and estimator), beside
# them those of the firmware in the loop (the simavr harness needs about 0.4 of one), then the
# computing tests marked slow (one process held to one core: the rig's runs take six minutes,
# and the other core would idle; the wheel's build and install among them, 45 s of one core),
# never two rig runs at once.
pytest: pytest-computing
	$(MAKE) --no-print-directory -j2 --output-sync=target pytest-beside-rig pytest-rig

pytest-computing:
	$(BIN)/pytest -n 2 --dist loadscope -m "not real_time and not slow"

pytest-beside-rig:
	$(BIN)/pytest -m real_time tests/fil
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/pytest -m "slow and not real_time"

pytest-fil:
	$(BIN)/pytest -m real_time tests/fil

pytest-rig:
	$(BIN)/pytest -m real_time --ignore=tests/fil

# The tests never import a study; this keeps each one importable and its options parsed.
studies-check:
	$(BIN)/python -m studies --check

study: setup
	@test -n "$(NAME)" || { $(BIN)/python -m studies; echo "usage: make study NAME=... [ARGS=...]" >&2; exit 2; }
	$(BIN)/python -m studies $(NAME) $(ARGS)

flash:
	@test -n "$(PORT)" || { echo "usage: make flash PORT=/dev/ttyACM0 ('gyrotens ports' lists them)" >&2; exit 2; }
	@command -v avrdude >/dev/null || { echo "avrdude is missing: make lab" >&2; exit 2; }
	$(MAKE) --no-print-directory -C firmware avr
	tools/check-bod.sh $(PORT) $(PROGRAMMER)
	avrdude -p atmega2560 -c $(PROGRAMMER) -P $(PORT) -b 115200 -D -U flash:w:$(FIRMWARE_ELF):e

clean:
	rm -rf build firmware/build out

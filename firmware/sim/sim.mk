# Firmware-in-the-loop harness (simavr) and its self-test firmware.
# Included by firmware/Makefile; also usable alone: make -C firmware -f sim/sim.mk sim
# Paths are relative to firmware/.

SIM_DIR      := sim
SIM_BUILD    := build/sim
SIM_HARNESS  := $(SIM_BUILD)/fil_harness
SIM_SELFTEST := $(SIM_BUILD)/selftest.elf
SIM_CC       ?= gcc
SIM_CFLAGS   := -std=gnu11 -O2 -Wall -Wextra -Werror -I/usr/include/simavr
SIM_LDLIBS   := -lsimavrparts -lsimavr -lpthread -lutil -lm
SIM_AVR_CC   ?= avr-gcc
SIM_AVR_FLAGS := -mmcu=atmega2560 -DF_CPU=16000000UL -Os -std=gnu11 -Wall -Wextra -Werror

.PHONY: sim fil-cycles

sim: $(SIM_HARNESS) $(SIM_SELFTEST)

$(SIM_HARNESS): $(SIM_DIR)/fil_harness.c $(SIM_DIR)/sim_spi.h $(SIM_DIR)/sim_uart.h $(SIM_DIR)/sim_rx.h \
                $(SIM_DIR)/sim.mk
	@mkdir -p $(@D)
	$(SIM_CC) $(SIM_CFLAGS) -o $@ $< $(SIM_LDLIBS)

$(SIM_SELFTEST): $(SIM_DIR)/selftest/selftest.c $(SIM_DIR)/sim.mk
	@mkdir -p $(@D)
	$(SIM_AVR_CC) $(SIM_AVR_FLAGS) -o $@ $< -lm

# Control-step cycle figures of the real firmware (FIL, all four wheels at 715 rpm).
# Named fil-cycles: firmware/Makefile has its own `cycles` (bench/cycles.c).
fil-cycles: sim $(ELF)
	$(SIM_DIR)/cycles.sh

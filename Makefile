# Two commands: `make demo` and `make test`. Both create .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-slow bench fuzz clean toolchain sigrok

DRIVE_CORE := hil/world/_drive_core.so
SERVO_CORE := hil/servobus/_servo_core.so
BOARD_CORE := hil/mcu/_board_core.so

CORES := $(DRIVE_CORE) $(SERVO_CORE) $(BOARD_CORE)

# `make` alone: the venv and the compiled cores, nothing run
setup: $(STAMP) $(CORES)

$(BIN)/python:
	$(PY) -m venv $(VENV)

# installed again when the pins change: pyproject.toml, or the pins in this file
$(STAMP): pyproject.toml Makefile | $(BIN)/python
	$(BIN)/pip install -q --disable-pip-version-check -e '.[test,grnn,dask]'
	# pypot's serial layer for the stock-client tests (issue 42); its declared dependencies
	# pull OpenCV, which pypot.dynamixel never imports
	$(BIN)/pip install -q --disable-pip-version-check --no-deps pypot==5.0.2
	$(MAKE) $(CORES)
	touch $(STAMP)

# the drive bank's compiled step (hil/world/drive_core.py), by the pinned ziglang's cc for
# the baseline CPU (the tree may be copied to another machine); no fused multiply-add, so
# its duties are numpy's bits
$(DRIVE_CORE): hil/world/drive_core.c | $(BIN)/python
	$(BIN)/python -m ziglang cc -mcpu=baseline -O2 -shared -fPIC -ffp-contract=off -o $@ $<

# the AX-12s' SYNC_WRITE and READ, and a cycle's status reads on the line, compiled
# (hil/servobus/servo_core.py, reads_core.py), built the same way:
# the same bits as the Python servos (exp and rint from the C library, as CPython's)
$(SERVO_CORE): hil/servobus/servo_core.c hil/servobus/reads_core.c hil/servobus/servo_core.h \
		| $(BIN)/python
	$(BIN)/python -m ziglang cc -mcpu=baseline -O2 -shared -fPIC -ffp-contract=off -o $@ \
		$(filter %.c,$^)

# the ELF board's event heap, USART2 and poll waits compiled (hil/mcu/board_core.py),
# built the same way: integers only, the Python model's in the same order
$(BOARD_CORE): hil/mcu/board_core.c | $(BIN)/python
	$(BIN)/python -m ziglang cc -mcpu=baseline -O2 -shared -fPIC -o $@ $<

# The ARM toolchain for STM32F411 ELFs (hexhil sdk build --target stm32f411, the ELF tests):
# Debian's packages, installed here when missing and we are root, else the line to run.
ARM_PACKAGES := gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi gdb-multiarch
toolchain:
	@if command -v arm-none-eabi-gcc >/dev/null && command -v gdb-multiarch >/dev/null && \
	    test -f "$$(arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard \
	        -mfpu=fpv4-sp-d16 -print-file-name=libc_nano.a)"; then :; \
	elif [ "$$(id -u)" = 0 ]; then \
	    apt-get update && apt-get install -y $(ARM_PACKAGES); \
	else \
	    echo "the ARM toolchain is missing; install it with:"; \
	    echo "  sudo apt-get install -y $(ARM_PACKAGES)"; exit 1; \
	fi

# sigrok-cli, which writes the logic-analyser captures (.sr) the capture import tests read
# (hexhil trace import reads .sr itself): Debian's package, installed the same way
sigrok:
	@if command -v sigrok-cli >/dev/null; then :; \
	elif [ "$$(id -u)" = 0 ]; then \
	    apt-get update && apt-get install -y sigrok-cli; \
	else \
	    echo "sigrok-cli is missing; install it with:"; \
	    echo "  sudo apt-get install -y sigrok-cli"; exit 1; \
	fi

demo: $(STAMP) $(CORES)
	$(BIN)/hexhil demo

test: $(STAMP) $(CORES) toolchain sigrok
	$(BIN)/python -m pytest -q

test-slow: $(STAMP) $(CORES) toolchain sigrok
	$(BIN)/python -m pytest -q -m slow

bench: $(STAMP) $(CORES) toolchain sigrok
	$(BIN)/python -m bench

# hostile inputs for every parser and loader (issue 20); FUZZ="--scale 0.1" for a short run
fuzz: $(STAMP) $(CORES)
	$(BIN)/python -m fuzz $(FUZZ)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache $(DRIVE_CORE) $(SERVO_CORE) $(BOARD_CORE)

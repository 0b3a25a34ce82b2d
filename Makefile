# Two commands: `make demo` and `make test`. Both create .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-slow bench fuzz clean toolchain gl sigrok

# the compiled cores' sources: pip builds them (setup.py's build_ext), so an edit reinstalls
CORE_SOURCES := setup.py hil/native.py hil/world/drive_core.c hil/world/drive_layout.py \
	hil/servobus/servo_core.c hil/servobus/servo_layout.py protocol/dynamixel/ax12.py \
	hil/servobus/reads_core.c hil/servobus/servo_core.h hil/mcu/board_core.c \
	hil/mcu/board_layout.py hil/mcu/armv7m.py hil/mcu/timebase.py hil/mcu/platform.py \
	hil/mcu/gpio_registers.py hil/mcu/usart_registers.py

# `make` alone: the venv and the compiled cores, nothing run
setup: $(STAMP)

$(BIN)/python:
	$(PY) -m venv $(VENV)

# installed again when the pins change (pyproject.toml, the pins in this file) or a compiled
# core's source does: pip builds the cores (setup.py) beside their Python modules
$(STAMP): pyproject.toml Makefile $(CORE_SOURCES) | $(BIN)/python
	$(BIN)/pip install -q --disable-pip-version-check -e '.[test,grnn,dask]'
	# pypot's serial layer for the stock-client tests; its declared dependencies
	# pull OpenCV, which pypot.dynamixel never imports
	$(BIN)/pip install -q --disable-pip-version-check --no-deps pypot==5.0.2
	touch $(STAMP)

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

# Offscreen OpenGL for hexhil render and its tests (EGL through libglvnd; MuJoCo's renderer
# loads it): Debian's package, installed the same way.
GL_PACKAGES := libegl1
gl:
	@if ldconfig -p 2>/dev/null | grep -q 'libEGL\.so\.1 '; then :; \
	elif [ "$$(id -u)" = 0 ]; then \
	    apt-get update && apt-get install -y $(GL_PACKAGES); \
	else \
	    echo "offscreen OpenGL (libEGL) is missing; install it with:"; \
	    echo "  sudo apt-get install -y $(GL_PACKAGES)"; exit 1; \
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

demo: $(STAMP)
	$(BIN)/hexhil demo

# the suite starts some hundred Python processes from this tree: each reads the bytecode
# cache the first one wrote, even where the caller's environment says not to write one
# (PYTHONDONTWRITEBYTECODE; the cache, __pycache__/, is ignored by git)
TEST_ENV := PYTHONDONTWRITEBYTECODE=

test: $(STAMP) toolchain gl sigrok
	$(TEST_ENV) $(BIN)/python -m pytest -q -n auto --maxprocesses 4 --dist loadfile

test-slow: $(STAMP) toolchain gl sigrok
	$(TEST_ENV) $(BIN)/python -m pytest -q -m slow

bench: $(STAMP) toolchain sigrok
	$(BIN)/python -m bench

# hostile inputs for every parser and loader; FUZZ="--scale 0.1" for a short run
fuzz: $(STAMP)
	$(BIN)/python -m fuzz $(FUZZ)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache hil/world/_drive_core.so \
		hil/servobus/_servo_core.so hil/mcu/_board_core.so

# Two commands: `make demo` and `make test`. Both create .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow bench fuzz clean

DRIVE_CORE := hil/world/_drive_core.so

$(STAMP): pyproject.toml hil/world/drive_core.c
	test -d $(VENV) || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --disable-pip-version-check -e '.[test,grnn,dask]'
	$(MAKE) $(DRIVE_CORE)
	touch $(STAMP)

# the drive bank's compiled step (hil/world/drive_core.py), by the pinned ziglang's cc for
# the baseline CPU (the tree may be copied to another machine); no fused multiply-add, so
# its duties are numpy's bits
$(DRIVE_CORE): hil/world/drive_core.c
	$(BIN)/python -m ziglang cc -mcpu=baseline -O2 -shared -fPIC -ffp-contract=off -o $@ $<

demo: $(STAMP)
	$(BIN)/hexhil demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

bench: $(STAMP)
	$(BIN)/python -m bench

# hostile inputs for every parser and loader (issue 20); FUZZ="--scale 0.1" for a short run
fuzz: $(STAMP)
	$(BIN)/python -m fuzz $(FUZZ)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache $(DRIVE_CORE)

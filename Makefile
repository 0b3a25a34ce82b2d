# Two commands: `make demo` and `make test`. Both create .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow bench fuzz clean

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --disable-pip-version-check -e '.[test,grnn,dask]'
	touch $(STAMP)

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
	rm -rf $(VENV) build *.egg-info .pytest_cache

# The two set-up commands: `make demo` and `make test`. Each builds the virtual environment on its own.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
# Tests run the optional backends too (their tests build small random models locally): torch comes from the
# pinned wheels already on these machines, see pyproject.toml. The dev extra brings the pinned ruff and mypy.
TEST_EXTRAS ?= dev,yolo,dinov3,gemini,dask
DEMO_OUT ?= out/demo

.PHONY: demo test venv clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip

$(VENV)/.installed-core: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -q -e .
	@touch $@

$(VENV)/.installed-test: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -q -e '.[$(TEST_EXTRAS)]'
	@touch $@

venv: $(VENV)/.installed-core

demo: $(VENV)/.installed-core
	$(PY) -m coastforge.demo --out $(DEMO_OUT)

# lint (ruff, the rules in pyproject.toml) and types (mypy on the core modules) first: either failing fails the target
test: $(VENV)/.installed-test
	$(PY) -m ruff check src tests
	$(PY) -m mypy
	./scripts/install-test-tools.sh
	$(PY) -m pytest -q -n 2 --dist loadfile

clean:
	rm -rf $(VENV) out .pytest_cache

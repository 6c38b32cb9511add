# The two set-up commands: `make demo` and `make test`. Each builds the virtual environment on its own.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
EXTRAS ?= dev
DEMO_OUT ?= out/demo

.PHONY: demo test test-core venv clean

$(VENV)/.installed-$(EXTRAS): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e '.[$(EXTRAS)]'
	@touch $@

venv: $(VENV)/.installed-$(EXTRAS)

demo: $(VENV)/.installed-$(EXTRAS)
	$(PY) -m coastforge.demo --out $(DEMO_OUT)

test: $(VENV)/.installed-$(EXTRAS)
	$(PY) -m pytest -q -n 2 --dist loadfile

clean:
	rm -rf $(VENV) out .pytest_cache

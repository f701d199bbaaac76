# Quick start (see README):  make train task=stage6   |   make test
# Each target creates .venv on first use (Python 3.11) and installs mjnav into it.

# The interpreter of .venv: PYTHON if given; else the distribution's /usr/bin/python3.11 where it
# can make a venv (Debian and Ubuntu build it with PGO and LTO; mjnav's step is mostly interpreted
# glue and ran 1.08-1.11x faster on it than on a default pyenv build, which has neither: see
# docs/performance.md); else python3.11 on PATH.
PYTHON ?= $(or $(shell /usr/bin/python3.11 -c "import ensurepip, venv" 2>/dev/null && echo /usr/bin/python3.11),python3.11)
VENV   ?= .venv
# The CPU build where a local wheel provides it (our dev and CI machines); from PyPI on Linux this
# pin is the default (CUDA) build. On a GPU box: TORCH=torch args="train.device=cuda".
TORCH  ?= torch==2.13.0
task   ?= stage6
args   ?=

BIN := $(VENV)/bin
STAMP := $(VENV)/.mjnav-installed

.PHONY: setup train demo test bench export clean

$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null || { echo "$(PYTHON) not found: set PYTHON=/path/to/python3.11"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "$(TORCH)"
	$(BIN)/python -m pip install -q -e ".[test]"
	@touch $(STAMP)

setup: $(STAMP)

train: $(STAMP)
	$(BIN)/python scripts/train.py task=$(task) $(args)

demo: $(STAMP)
	$(BIN)/python scripts/demo.py task=$(task) $(args)

test: $(STAMP)
	$(BIN)/python -m pytest tests $(args)

bench: $(STAMP)
	$(BIN)/python scripts/benchmark.py task=$(task) $(args)

export: $(STAMP)
	$(BIN)/python scripts/export_world.py task=$(task) $(args)

clean:
	rm -rf $(VENV) .pytest_cache

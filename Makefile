# Two commands from a fresh clone: `make demo` and `make test`. Both create the virtual
# environment on first use and reinstall when pyproject.toml changes; the install ends by
# compiling the Numba kernels into their disk cache (`elastoflow warmup`, about a minute on
# 2 cores), so that the first run starts at once instead of compiling as it goes.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,viewer]'
	$(BIN)/elastoflow warmup
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m elastoflow.demo

test: $(STAMP)
	$(BIN)/python -m pytest -n 2 --durations=15

test-fast: $(STAMP)
	$(BIN)/python -m pytest -n 2 -m "not slow"

bench: $(STAMP)
	$(BIN)/python -m benchmarks

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy src

clean:
	rm -rf $(VENV) out benchmarks/results

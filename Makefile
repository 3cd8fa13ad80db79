# One target per gate; CI (.ci/run) runs `make test`.
VENV := .venv
BIN := $(VENV)/bin
# Off-screen GL backend found to work by scripts/setup.sh (egl, else osmesa); override on the command line.
export MUJOCO_GL ?= $(shell cat $(VENV)/mujoco_gl 2>/dev/null || echo egl)

.PHONY: install demo render-demo test lint type docs bench reproduce-check

install: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml scripts/setup.sh
	bash scripts/setup.sh dev
	touch $@

demo: install  ## the main job: a short real DDPG+HER training on tsrl/UR5eReach-v0 (fs1), report + learning curves in results/quick-reach/
	$(BIN)/tsrl experiment quick-reach

render-demo: install  ## renders the UR5e reach scene at home and a few poses to results/show/*.png
	$(BIN)/tsrl show --out-dir results/show

test: install  ## the test suite, without the slow checks
	$(BIN)/python -m pytest -m "not slow" -n auto --durations=10

lint:
	$(BIN)/ruff check . && $(BIN)/ruff format --check .

type:  ## mypy over src/tsrl ([tool.mypy] in pyproject.toml)
	$(BIN)/mypy

docs: install  ## the docs site (mkdocs.yml) into site/, strict: a broken link, anchor or API reference fails
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

reproduce-check: install  ## re-derives from the committed data (studies/QUESTION/SCREEN/, docs/results/benchmarks/): every study's comparisons, the across-study table (docs/results/comparisons-all.md), every benchmark table
	$(BIN)/python scripts/readme_comparisons.py --check
	$(BIN)/python scripts/benchmark_tables.py
	$(BIN)/python -m pytest -q -p no:cacheprovider tests/experiments/test_across.py

bench: install  ## speed benchmarks (task maps, IK, env step): each prints a table; learning studies: tsrl experiment, studies/*/
	$(BIN)/python -m pip install -q -e ".[bench]"
	cd benchmarks && ../$(BIN)/python taskmaps.py && ../$(BIN)/python ik.py && ../$(BIN)/python env_step.py

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out/fossen-strand-1999

.PHONY: demo test check lint types docs lock bench study observer-benchmark tuning-study thruster-study clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml constraints.txt | $(BIN)/activate
	$(BIN)/pip install --quiet -c constraints.txt -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml constraints.txt | $(BIN)/activate
	$(BIN)/pip install --quiet -c constraints.txt -e '.[dev]'
	touch $@ $(VENV)/.installed

$(VENV)/.installed-docs: pyproject.toml constraints.txt | $(BIN)/activate
	$(BIN)/pip install --quiet -c constraints.txt -e '.[docs]'
	touch $@ $(VENV)/.installed

demo: $(VENV)/.installed
	mkdir -p $(dir $(OUT))
	$(BIN)/lookout reproduce fossen-strand-1999 --out $(OUT)

test: $(VENV)/.installed-dev
	$(BIN)/python -m pytest -q -n auto --dist loadgroup --max-worker-restart=0 --durations=25

# The loop while one works: lint, types and the tests not marked slow (docs/testing.md).
check: lint types $(VENV)/.installed-dev
	$(BIN)/python -m pytest -q -n auto --dist loadgroup --max-worker-restart=0 -m "not slow"

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

types: $(VENV)/.installed-dev
	$(BIN)/mypy

# constraints.txt: the versions the suite passed with, which `make demo` and `make test`
# install. Refresh it in a new environment from the registries' newest releases, then
# run `make test` on a fresh clone before committing it.
lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/pip install --quiet --upgrade pip
	.lock-venv/bin/pip install --quiet -e '.[dev,docs]'
	( echo "# The versions make demo and make test install (pip's -c); refreshed with make lock." ; \
	  .lock-venv/bin/pip freeze --exclude-editable | sort -f ) > constraints.txt
	rm -rf .lock-venv

# The documentation site in site/ (mkdocs.yml): docs/ and an API reference from the
# docstrings. --strict fails the build on a broken link or anchor, a missing image or a
# cross-reference that finds nothing. NO_MKDOCS_2_WARNING quiets mkdocs-material's
# banner about its own future, which is not a finding about these docs.
docs: $(VENV)/.installed-docs
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# The README's example study: two campaigns, their reports, and the figures in docs/study/.
STUDIES ?= out/studies
study: $(VENV)/.installed
	mkdir -p $(STUDIES) docs/study
	$(BIN)/lookout campaign run examples/dp-study.toml --out $(STUDIES)/dp-study.zarr
	$(BIN)/lookout campaign report $(STUDIES)/dp-study.zarr --figures docs/study/dp-study
	$(BIN)/lookout campaign run examples/kim-model-error.toml --out $(STUDIES)/kim-model-error.zarr
	$(BIN)/lookout campaign report $(STUDIES)/kim-model-error.zarr --figures docs/study/kim-model-error

# The observer benchmark (docs/choosing-an-observer.md): every observer on each shipped
# plant; its tables and figures are copied to docs/benchmark/.
BENCHMARK ?= out/benchmark
observer-benchmark: $(VENV)/.installed
	$(BIN)/lookout benchmark observers --out $(BENCHMARK)
	for plant in dp-vessel cybership-ii manipulator; do \
		mkdir -p docs/benchmark/$$plant && cp $(BENCHMARK)/$$plant/table.md $(BENCHMARK)/$$plant/figures/*.png docs/benchmark/$$plant/; \
	done
	$(BIN)/lookout benchmark dead-reckoning --out $(BENCHMARK)/dead-reckoning
	mkdir -p docs/benchmark/dead-reckoning && cp $(BENCHMARK)/dead-reckoning/table.md $(BENCHMARK)/dead-reckoning/drift.png docs/benchmark/dead-reckoning/

# docs/tuning/: lookout tune on six cases and the table of docs/tuning.md's study (about 12 minutes on 2 cores)
tuning-study: $(VENV)/.installed
	$(BIN)/python docs/tuning/study.py

# docs/thrusters.md's allocation study: the papers' loops through thrusters (about 17 minutes on 2 cores)
thruster-study: $(VENV)/.installed
	$(BIN)/python docs/thrusters/study.py

bench: $(VENV)/.installed
	$(BIN)/python benchmarks/throughput.py

clean:
	rm -rf $(VENV) out site

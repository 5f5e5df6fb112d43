# texplorer: every target creates its own virtual environment on first use, with the tested versions of
# every dependency (constraints.txt); `make lock` refreshes them to the newest releases.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
LOCK   := constraints.txt
TOOLS_LOCK := constraints-rocrate.txt
STAMP  := $(VENV)/.installed-$(shell $(PYTHON) -c "import hashlib;print(hashlib.sha256(open('pyproject.toml','rb').read()+open('$(LOCK)','rb').read()+open('$(TOOLS_LOCK)','rb').read()).hexdigest()[:12])")
DB     ?= texplorer-data
JOBS   ?= 2

.PHONY: demo test test-fast hooks bench lint docs clean install lock

install: $(STAMP)

$(STAMP): pyproject.toml $(LOCK) $(TOOLS_LOCK)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e '.[dev,docs]'
	# The RO-Crate validator the export tests run, in an environment of its own: it requires rich < 14,
	# import-linter rich >= 14.2 (constraints-rocrate.txt)
	$(PYTHON) -m venv $(VENV)/tools/rocrate
	$(VENV)/tools/rocrate/bin/python -m pip install --quiet -r $(TOOLS_LOCK)
	# numba's machine code of the feature kernels into its cache now, once, instead of in every process of
	# the first command that extracts features (scanner.workflows.demo.compile_kernels); a warm-up only: if it
	# fails, the install stands and the tests name what is broken
	-$(BIN)/python -c "from scanner.workflows.demo import compile_kernels as c; print(f'feature kernels compiled in {c():.0f} s')"
	rm -f $(VENV)/.installed-*
	touch $@

demo: $(STAMP)
	$(BIN)/texplorer demo --db $(DB)

# Every test: tests/unit and tests/system (CONTRIBUTING.md). CI runs this.
test: $(STAMP)
	$(BIN)/python -m pytest -n $(JOBS) --durations=15

# The unit tests only: the loop to run while working (under a minute on two cores).
test-fast: $(STAMP)
	$(BIN)/python -m pytest tests/unit -n $(JOBS) -q

# The commit-msg check of CONTRIBUTING.md, for this clone.
hooks:
	git config core.hooksPath .githooks

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

# The documentation site (mkdocs.yml, pages in docs/) into site/, warnings as errors; no network needed.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports --no-logo

# The newest releases pip resolves today, in a scratch environment, written as the new constraints; then
# `make test` installs and tests exactly them. Commit constraints.txt when the tests pass.
lock:
	rm -rf .venv-lock
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet --upgrade pip
	.venv-lock/bin/python -m pip install --quiet -e '.[dev,docs]'
	{ echo "# Tested versions of every dependency (make lock; installed by make install with pip -c)."; \
	  echo "# Python $$(.venv-lock/bin/python -c 'import platform; print(platform.python_version())'), $$(date -u +%Y-%m-%d)"; \
	  .venv-lock/bin/python -m pip freeze --exclude-editable --all | grep -v '^pip=='; } > $(LOCK).new
	mv $(LOCK).new $(LOCK)
	rm -rf .venv-lock
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet --upgrade pip
	.venv-lock/bin/python -m pip install --quiet roc-validator rocrate
	{ sed -n '1,3p' $(TOOLS_LOCK); .venv-lock/bin/python -m pip freeze --all | grep -v '^\(pip\|setuptools\)=='; } \
	  > $(TOOLS_LOCK).new
	mv $(TOOLS_LOCK).new $(TOOLS_LOCK)
	rm -rf .venv-lock

clean:
	rm -rf $(VENV) .venv-lock build site *.egg-info .pytest_cache .ruff_cache

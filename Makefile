# Set-up and checks for tanksynth on a fresh Debian machine (Python 3.11, root).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# Two stamps: the runtime install (`make demo` needs nothing more) and the development tools on
# top of it (pytest, mypy, Sphinx, ...: `make test`, `test-fast`, `bench`, `fuzz`).
RUNTIME_STAMP := $(VENV)/.runtime-installed
STAMP  := $(VENV)/.installed

.PHONY: demo test test-fast fuzz bench tex browser clean docs bytecode

$(RUNTIME_STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $(RUNTIME_STAMP)

$(STAMP): $(RUNTIME_STAMP) pyproject.toml
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# Byte-compile the package, as `pip install` of a wheel does: an editable install under
# PYTHONDONTWRITEBYTECODE=1 would otherwise compile every module at every command (~0.2 s).
# Checked-hash .pyc files: every import compares the source's hash, so a stale .pyc is never
# used (a timestamp .pyc keys on mtime in whole seconds and size: an edit of the same size in the
# second of compiling kept the old code). Every module is compiled again each time (~0.5 s).
bytecode: $(RUNTIME_STAMP)
	@$(PY) -m compileall -q --invalidation-mode checked-hash tanksynth

# pdflatex/latexmk/pdftotext for the reports and a C compiler (exported laws, the simulator's
# compiled kernel; both fall back or skip without one), from Debian packages when missing.
tex:
	@if ! command -v pdflatex >/dev/null || ! command -v latexmk >/dev/null || ! command -v pdftotext >/dev/null \
			|| ! command -v gcc >/dev/null; then \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends \
			texlive-latex-base texlive-latex-recommended latexmk poppler-utils gcc libc6-dev >/dev/null; \
	fi

demo: $(RUNTIME_STAMP) bytecode
	$(VENV)/bin/tanksynth run -o tanksynth-demo

# import-linter contracts (.importlinter: layers, verify never imports design, papers only
# in reports) first, then the test suite.
# Between them mypy type-checks the whole package ([tool.mypy] in pyproject.toml).
# A headless browser for the documentation's screenshot tests (tests/test_docs.py; they skip
# without one, so a failed install only costs those two tests).
browser:
	@if ! command -v chromium >/dev/null && ! command -v chromium-browser >/dev/null; then \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		( $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq \
			--no-install-recommends chromium fonts-dejavu-core >/dev/null ) \
			|| echo "chromium not installed: the browser tests of tests/test_docs.py skip"; \
	fi

test: $(STAMP) tex browser bytecode
	$(VENV)/bin/lint-imports --no-logo
	$(VENV)/bin/mypy
	$(PY) -m pytest -n 2 -q

# The edit-test loop: every test but those marked slow (notebooks, the docs build, examples and
# campaigns run end to end, LaTeX, C compiles, fuzzing at scale; `make test` runs them too):
# 1,716 of 2,003 tests, about 90 s of CPU, under a minute when both cores are free.
test-fast: $(STAMP) bytecode
	$(PY) -m pytest -n 2 -q -m "not slow"

# The adversarial property tests at ten times the scale of `make test` (>= 20,000 generated specs
# and edited result directories through the CLI entry point), randomised on every run.
fuzz: $(STAMP)
	TANKSYNTH_FUZZ_SCALE=10 $(PY) -m pytest -n 2 -q tests/fuzz/test_cli_fuzz.py --hypothesis-show-statistics

# The benchmarks against compiled contenders (numba, JAX: the `bench` extra, installed here
# only), then the README's tables rendered from the results they wrote (benchmarks/report.py).
BENCH_STAMP := $(VENV)/.bench-installed
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[dev,bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP) bytecode
	@for script in benchmarks/*.py; do \
		case $$script in benchmarks/report.py) continue;; esac; \
		echo "== $$script"; $(PY) $$script || exit 1; done
	$(PY) benchmarks/report.py --write

# HTML documentation (Sphinx + myst-nb, pydata-sphinx-theme): quick start, plant and method pages
# generated from the code, the API reference of tanksynth's public names (developers: every
# module), the notebooks executed. Warnings are errors. Open docs/_build/html/index.html.
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[dev,docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(PY) -m sphinx -W --keep-going -b html docs docs/_build/html

# Scaffold a design method into its family and add its table row (scripts/add_method.py --help):
# make method NAME=residual_bank FAMILY=fault KIND=detector [SUMMARY="..."] [PLANT_FROM=spec.toml]
.PHONY: method
method: $(STAMP)
	$(PY) scripts/add_method.py "$(NAME)" --family "$(FAMILY)" --kind "$(KIND)" \
		$(if $(SUMMARY),--summary "$(SUMMARY)") $(if $(PLANT_FROM),--plant-from "$(PLANT_FROM)")

clean:
	rm -rf $(VENV) tanksynth-demo .pytest_cache docs/_build docs/_generated

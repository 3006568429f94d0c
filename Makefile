# brdfpipe: two commands set everything up on a fresh machine.
#   make run    create .venv, install, check Mitsuba's LLVM backend, run the workflow
#   make test   the same set-up, then the test suite (unit, workflow dry-run/lint, tiny run)
#   make bench  the benchmarks in benches/ (they print ratios; they never fail a build)

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
SMK    := $(VENV)/bin/snakemake
STAMP  := $(VENV)/.brdfpipe-installed
# The Slurm executor plug-in lives apart from the venv's site-packages, on
# PYTHONPATH only for Slurm runs: Snakemake imports every installed plug-in at
# start-up, and this one imports pandas (0.4 s more for every local snakemake).
SLURM_PLUGINS := $(VENV)/slurm-plugins
SLURM_STAMP   := $(SLURM_PLUGINS)/.installed
CONFIG ?= config/config.yaml
CORES  ?= all
# Every workflow job is its own Python process: let them keep the library's
# compiled bytecode (some environments set this variable, and then each job
# compiles every module it imports again).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test bench setup llvm chromium dryrun lint clean slurm-test slurm-plugins report

setup: $(STAMP) llvm

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[workflow,test]"
	touch $@

# Mitsuba's llvm_ad_rgb variant needs LLVM 19 (Debian's libllvm19); the LLVM 14/15
# that Debian 12 ships by default crash or are refused by Dr.Jit.
llvm: $(STAMP)
	@if ! ldconfig -p | grep -q 'libLLVM\.so\.19'; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing libllvm19 (Mitsuba's CPU backend needs LLVM 19)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null; \
	  else \
	    echo "Mitsuba's llvm_ad_rgb variant needs LLVM 19. Run:  sudo apt-get install libllvm19" >&2; \
	    exit 1; \
	  fi; \
	fi
	@$(PY) -c "import drjit.llvm as L; assert list(L.Float([1, 2, 3]) * 2) == [2, 4, 6]; print('Dr.Jit LLVM backend: ok')"

# Debian's chromium for the explorer's browser tests (tests/test_explorer.py) and
# its benchmark: installed when root and missing; otherwise those tests are
# skipped with the reason, so this target never fails the build.
chromium:
	@if ! command -v chromium >/dev/null && ! command -v chromium-browser >/dev/null; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing chromium (the explorer's browser tests)"; \
	    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } \
	      || echo "chromium could not be installed: the explorer's browser tests will be skipped" >&2; \
	  else \
	    echo "no chromium: the explorer's browser tests will be skipped (sudo apt-get install chromium)" >&2; \
	  fi; \
	fi

# pyproject's `slurm` extra, without dependencies (the venv has the rest)
slurm-plugins: $(SLURM_STAMP)
$(SLURM_STAMP): pyproject.toml $(STAMP)
	rm -rf $(SLURM_PLUGINS)
	$(PY) -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['slurm']))" > $(VENV)/slurm-requirements.txt
	$(PY) -m pip install --quiet --no-deps --target $(SLURM_PLUGINS) -r $(VENV)/slurm-requirements.txt
	PYTHONPATH=$(SLURM_PLUGINS) $(PY) -c "import snakemake_executor_plugin_slurm, snakemake_executor_plugin_slurm_jobstep"
	touch $@

run: setup
	$(SMK) --cores $(CORES) --configfile $(CONFIG)

# The Snakemake report of a finished run (make run first, same CONFIG): every
# figure, table and error map with captions holding the run's claims and numbers.
report: setup
	$(SMK) --configfile $(CONFIG) --report results/report.zip

test: setup lint chromium $(SLURM_STAMP)
	$(PY) -m pytest -q -n 2 --maxschedchunk 2 --durations=20

bench: setup
	$(PY) benches/run_all.py

dryrun: $(STAMP)
	$(SMK) -n --configfile tests/config/tiny.yaml

lint: $(STAMP)
	$(VENV)/bin/snakefmt --check workflow
	$(SMK) --lint --configfile tests/config/tiny.yaml

# The workflow on a real single-node Slurm (root: installs and starts Debian's
# slurmctld/slurmd/munge unless sinfo answers), checked against Slurm's job
# records and against a local run (byte-identical results/). See profiles/slurm/.
slurm-test: setup $(SLURM_STAMP)
	$(PY) tests/slurm/run_slurm_test.py

clean:
	rm -rf results/* .snakemake logs benchmarks

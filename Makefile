# evoscen — two commands on a fresh machine: `make demo` and `make test`.
# `make demo` runs `make setup-core` first (the .venv with the pinned requirements, then colcon build);
# `make test` runs `make setup`: the core and everything the suite tests (the example plug-ins, the
# export tools and their checkers, the SUMO reference). Both idempotent. `make test-core` is the
# lighter suite on the core alone (the tests of the parts not installed are skipped, each saying why).

PYTHON_BOOT ?= $(shell command -v python3.11 || command -v python3)
VENV        := .venv
PY          := $(VENV)/bin/python
WS          := ros2_ws
INSTALL     := $(WS)/install
REQ_STAMP   := $(VENV)/.requirements-installed
# the example plug-in packages under examples/ that make setup installs (see $(EXAMPLES_STAMP) below)
EXAMPLE_PACKAGES := examples/fiss_sut examples/sumo_sut
EXAMPLES_STAMP   := $(VENV)/.examples-installed
# the export tools' packages (requirements-export.txt, docs/export.md "Packages")
EXPORT_STAMP     := $(VENV)/.export-requirements-installed
# the SUMO reference (requirements-bench.txt): scripts/bench.py's comparison, the Krauss-vs-SUMO test
# and examples/sumo_sut; evoscen itself never needs SUMO
BENCH_STAMP      := $(VENV)/.bench-requirements-installed
# Run anything with the workspace overlay (colcon's install/setup.sh) on top of the venv.
RUN         := . $(VENV)/bin/activate && . $(INSTALL)/setup.sh &&
DEMO_OUT    ?= runs/demo
PYTEST_ARGS ?=

.PHONY: setup setup-core build demo test test-core test-fast test-repeat lint readme-table bench clean

# the core: what evoscen needs to run scenarios, campaigns and experiments
setup-core: $(REQ_STAMP) build
# the core and everything the suite tests (the README's `make test`, and CI, run on this)
setup: setup-core $(EXAMPLES_STAMP) $(EXPORT_STAMP) $(BENCH_STAMP)

$(REQ_STAMP): requirements.txt requirements-runtime.txt
	@$(PYTHON_BOOT) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null || { \
	    echo "error: Python 3.11 not found (PYTHON_BOOT='$(PYTHON_BOOT)'); the ROS 2 Jazzy wheels need CPython 3.11: install it or run make PYTHON_BOOT=/path/to/python3.11"; exit 2; }
	test -x $(PY) || $(PYTHON_BOOT) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	touch $@

# The example plug-in packages (docs/plugins.md §17), installed editable into the .venv so that the
# suite tests them; their own pinned dependencies come from the index, evoscen's pins are kept
# (-c requirements-runtime.txt); the build backend is the .venv's setuptools (--no-build-isolation).
# examples/sumo_sut needs SUMO (requirements-bench.txt: installed first, same pins).
$(EXAMPLES_STAMP): $(REQ_STAMP) $(BENCH_STAMP) $(addsuffix /pyproject.toml,$(EXAMPLE_PACKAGES))
	$(PY) -m pip install --quiet --disable-pip-version-check --no-build-isolation -c requirements-runtime.txt \
	    $(addprefix -e ,$(EXAMPLE_PACKAGES))
	touch $@

# OpenSCENARIO / CommonRoad export (scripts/export_scenario.py): every dependency is pinned in the file,
# installed with --no-deps so that no pin of requirements.txt changes (commonroad-io's protobuf pin is
# left unmet on purpose: docs/export.md "Packages"); wheels only, ~35 s on the 2-core VM with a warm cache.
$(EXPORT_STAMP): $(REQ_STAMP) requirements-export.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --only-binary :all: -r requirements-export.txt
	touch $@

# --symlink-install: the install tree links to the sources (Python modules, share files), so an
# edited module is what the next test imports without a rebuild; rebuild after adding a file,
# an entry point or a package.
# colcon runs only when the build's inputs changed since the last successful build: the list of
# files under ros2_ws/src (a file added or removed) or the packages' setup.py/setup.cfg/package.xml;
# an edited module needs no rebuild (symlink install). BUILD_STAMP holds those inputs. A rebuild also
# drops numba's compiled-kernel caches (__pycache__/*.nbi, *.nbc, evoscen_sim/jit.py): a cached kernel
# names the modules of the kernels it calls, and numba loads it without checking that they still exist,
# so a moved or renamed module would fail every run with ModuleNotFoundError until they are deleted.
# After a rebuild scripts/warm_kernels.py compiles the kernels into that cache again (~40 s on the 2-core
# VM), once, rather than every Ray worker of the first experiment in parallel (docs/performance.md "Start-up").
BUILD_STAMP := $(INSTALL)/.evoscen-build-inputs
build: $(REQ_STAMP)
	@new=$$(cd $(WS)/src && { find . \( -name __pycache__ -o -name '*.egg-info' \) -prune -o -type f -print | LC_ALL=C sort; \
	    cat */setup.py */setup.cfg */package.xml 2>/dev/null | sha256sum; }); \
	if [ -f $(BUILD_STAMP) ] && [ "$$new" = "$$(cat $(BUILD_STAMP))" ]; then \
	    echo "build: up to date (no file added or removed under $(WS)/src, no package metadata changed)"; \
	else \
	    find $(WS)/src -path '*/__pycache__/*' \( -name '*.nbi' -o -name '*.nbc' \) -delete; \
	    ( . $(VENV)/bin/activate && cd $(WS) && colcon --log-base log build --symlink-install --base-paths src \
	        --build-base build --install-base install --event-handlers console_cohesion- summary- ) \
	    && ( $(RUN) python scripts/warm_kernels.py ) \
	    && printf '%s\n' "$$new" > $(BUILD_STAMP); \
	fi

demo: setup-core
	$(RUN) python scripts/run_scenario.py --sut mobil --out $(DEMO_OUT) --overwrite

# the whole suite; EVOSCEN_TEST_EXTRAS=required turns a missing part (a plug-in, SUMO, an export
# checker) into one error line at the start instead of skipped tests (tests/conftest.py)
test: setup
	$(RUN) EVOSCEN_TEST_EXTRAS=required python -m pytest $(PYTEST_ARGS)

# the suite on the core alone (make setup-core): the tests of the parts not installed are skipped
test-core: setup-core
	$(RUN) python -m pytest $(PYTEST_ARGS)

# the suite without the end-to-end tests (marker e2e: node graphs, CLI subprocesses, containers)
test-fast: setup
	$(RUN) EVOSCEN_TEST_EXTRAS=required python -m pytest -m "not e2e" $(PYTEST_ARGS)

# the timing-sensitive tests (node graphs: deaths, stalls, faults) run REPEAT times in a row; a table of
# passes per test (scripts/repeat_tests.py; docs/development.md "Repeating timing-sensitive tests")
REPEAT       ?= 10
REPEAT_TESTS ?= tests/test_graph.py tests/test_crash.py tests/test_plugin_faults.py \
                -k "kill or stall or sigint or sigterm or raising_in_the_graph"
test-repeat: setup
	$(RUN) python scripts/repeat_tests.py --times $(REPEAT) -- $(REPEAT_TESTS)

# ruff (pinned in requirements.txt; rules in ruff.toml); never reformats
lint: $(REQ_STAMP)
	$(VENV)/bin/ruff check .

# the README's results table, rewritten from the results file its marker names (results/readme.yaml;
# scripts/readme_table.py --check exits 1 if the README differs; tests/test_readme.py checks it)
readme-table: $(REQ_STAMP)
	$(PY) scripts/readme_table.py

$(BENCH_STAMP): requirements-bench.txt $(REQ_STAMP)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-bench.txt
	touch $@

bench: setup $(BENCH_STAMP)
	$(RUN) python scripts/bench.py --mode graph --sut-models --learned

clean:
	rm -rf $(WS)/build $(WS)/install $(WS)/log runs
	find $(WS)/src -path '*/__pycache__/*' \( -name '*.nbi' -o -name '*.nbc' \) -delete

# --- containers (docs/docker.md): docker or podman, whichever is installed --------------------------
.PHONY: docker-build docker-test docker-demo
DOCKER_DEMO_OUT ?= runs/docker-demo

docker-build:
	bash docker/build.sh test runtime user-sut fiss-sut

# the whole suite inside the test image, no network (loopback only: DDS stays inside the container)
docker-test:
	bash docker/build.sh test
	bash -c '. docker/engine.sh && $$ENGINE run --rm --network none --shm-size=256m localhost/evoscen-test:latest make test'

# the default scenario as a compose graph (one container per node); bag and report in DOCKER_DEMO_OUT
docker-demo:
	bash docker/build.sh runtime
	bash docker/compose-run.sh --out $(DOCKER_DEMO_OUT) -- --steps 3000 --seed 0

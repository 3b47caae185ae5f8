# vm_ros developer and CI entry points. Nothing here needs an activated venv.
#
#   make venv         create/refresh $(VENV) with ".[ros,dev,fast,opensim,mujoco,study]" pinned by constraints.txt,
#                     and compile the model step (Numba's cache)
#   make test         the whole pytest suite (ruff included) in a loopback-only network namespace,
#                     on TEST_WORKERS (2) pytest-xdist workers
#   make demo         the demo, in a loopback-only network namespace
#   make demo-closed-loop  muscle_node driving a MuJoCo elbow over ROS 2 (MCAP, PNG), same namespace
#   make bench        vm-ros bench (results in bench-results/), in a loopback-only namespace
#   make lint         ruff only
#   make constraints  re-resolve constraints.txt in fresh venvs (needs PyPI)
#   make clean

VENV ?= .venv
# Debian 12's own interpreter where it is installed, whatever python3 comes first on PATH: it is a
# statically linked build, faster than a shared-library build of the same Python for the kernel's
# compile and the node (docs/performance.md). PYTHON=... overrides it.
PYTHON ?= $(or $(wildcard /usr/bin/python3.11),python3)
COLCON_VENV ?= .venv-colcon

# Compile the model step into Numba's per-user cache now (vm_ros.model.jit.cache_root; a load of
# 0.3 s when these sources were compiled before), not in the first test or node start.
WARM_UP := $(VENV)/bin/python -c 'from vm_ros.model import kernel; kernel.warm_up()'
DEPS_STAMP := $(VENV)/.vm_ros-deps
PKG_STAMP := $(VENV)/.vm_ros-pkg
# Everything that ends up in the installed package: vm_ros is reinstalled when any of it changed
# (directories are listed too, so that added or deleted files count as a change).
PKG_SOURCES := setup.py package.xml \
	$(shell find vm_ros config msg_defs resource -name __pycache__ -prune -o -print 2>/dev/null)

.PHONY: all venv test demo demo-closed-loop bench lint clean constraints colcon-venv host-tools
.DEFAULT_GOAL := test

all: test

venv: host-tools $(PKG_STAMP)

# One rule, so that a new venv installs vm_ros once: the dependencies are (re)installed only when
# setup.py or constraints.txt is newer than $(DEPS_STAMP) (or the venv is new); otherwise vm_ros
# alone is reinstalled, whenever any of $(PKG_SOURCES) changed. A regular (non-editable) install:
# the ament layout lives in data_files. build/ is removed first, since setuptools would otherwise
# ship modules that were deleted from the source tree.
$(PKG_STAMP): setup.py constraints.txt $(PKG_SOURCES)
	@test -x $(VENV)/bin/python || { echo "$(PYTHON) -m venv $(VENV)"; $(PYTHON) -m venv $(VENV); }
	rm -rf build
	@if [ $(DEPS_STAMP) -nt setup.py ] && [ $(DEPS_STAMP) -nt constraints.txt ]; then \
	    echo "$(VENV)/bin/pip install --no-deps --force-reinstall ."; \
	    $(VENV)/bin/pip install --quiet --no-deps --force-reinstall .; \
	else \
	    echo '$(VENV)/bin/pip install -c constraints.txt ".[ros,dev,fast,opensim,mujoco,study]"'; \
	    $(VENV)/bin/pip install -c constraints.txt ".[ros,dev,fast,opensim,mujoco,study]" && touch $(DEPS_STAMP); \
	fi
	$(WARM_UP)
	@touch $@

# The colcon that test/test_packaging.py builds with; needs PyPI, so made here, outside the netns.
colcon-venv:
	PYTHON=$(PYTHON) scripts/colcon-venv $(COLCON_VENV)

# `ip` and `unshare` for scripts/netns-run; installed with apt-get only when missing (CI runs as root).
host-tools:
	@if ! command -v ip >/dev/null 2>&1 || ! command -v unshare >/dev/null 2>&1; then \
	    if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	        echo "ip/unshare missing: apt-get install -y iproute2 util-linux"; \
	        apt-get update -qq && \
	        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iproute2 util-linux; \
	    else \
	        echo "ip/unshare missing; install them with: sudo apt-get install -y iproute2 util-linux" >&2; \
	        exit 1; \
	    fi; \
	fi

# pytest's exit status is passed through as is: 5 (no tests collected) fails the target, with
# workers too. $(VENV)/bin/pytest, not `python -m pytest`: -m would put the source tree first on
# sys.path, and the suite is meant to exercise the installed package (data_files included).
# TEST_WORKERS pytest-xdist workers (2: the cores of the CI machine; each in a DDS domain of its
# own, test/conftest.py), tests handed out by work stealing; TEST_WORKERS=0 runs them in one process.
TEST_WORKERS ?= 2
test: venv colcon-venv
	scripts/netns-run $(VENV)/bin/pytest -q --durations=25 -n $(TEST_WORKERS) --dist worksteal test

demo: venv
	scripts/netns-run $(VENV)/bin/vm-ros demo

demo-closed-loop: venv
	scripts/netns-run $(VENV)/bin/vm-ros demo --closed-loop

bench: venv
	scripts/netns-run $(VENV)/bin/vm-ros bench --out bench-results

lint: $(PKG_STAMP)
	$(VENV)/bin/ruff check .

constraints:
	PYTHON=$(PYTHON) scripts/gen-constraints

clean:
	rm -rf $(VENV) $(COLCON_VENV) build *.egg-info .pytest_cache .ruff_cache

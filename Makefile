# PCVR: `make demo` and `make test` set up everything on a fresh Debian 12 machine.
# Steps are stamped, so a second run with nothing changed installs and rebuilds nothing.

SHELL       := /bin/bash
PYTHON_SYS  ?= python3.11
VENV        := .venv
PY          := $(VENV)/bin/python
SUDO        := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
APT_PACKAGES := build-essential cmake ninja-build libopenvdb-dev libboost-dev libboost-iostreams-dev libtbb-dev
# Python 3.11 with headers and venv: Debian's packages unless a working one is already there (e.g. pyenv).
APT_PYTHON  := python3.11 python3.11-venv python3.11-dev
NATIVE_SOURCES := $(shell find native/include native/src native/python -type f -not -name '*.pyc') \
                  native/CMakeLists.txt native/pyproject.toml
WHEEL_DIR   := dist
ADDON_SOURCES := $(shell find pcvr_addon -name '*.py')
EXTENSION_ZIP := $(WHEEL_DIR)/pcvr-$(shell sed -n 's/^version = "\(.*\)"/\1/p' blender_manifest.toml)-linux_x64.zip

.PHONY: all setup system native test demo bench extension clean

all: test

setup: $(VENV)/.native-stamp

# System packages: skip apt entirely when everything is present.
system:
	@missing=""; for p in $(APT_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || missing="$$missing $$p"; \
	done; \
	$(PYTHON_SYS) -c 'import sysconfig, os, sys, venv, ensurepip; sys.exit(not os.path.exists(sysconfig.get_paths()["include"] + "/Python.h"))' \
	  2>/dev/null || missing="$$missing $(APT_PYTHON)"; \
	if [ -n "$$missing" ]; then \
	  echo "Installing system packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing; \
	fi

$(VENV)/.deps-stamp: requirements.txt | system
	test -x $(PY) || $(PYTHON_SYS) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	touch $@

# The wheel is built in place (native/build/<tag>) so rebuilds are incremental; the lock keeps
# concurrent builds from sharing a build tree.
$(VENV)/.native-stamp: $(VENV)/.deps-stamp $(NATIVE_SOURCES)
	rm -f $(WHEEL_DIR)/pcvr_native-*.whl
	flock native/.build.lock $(PY) -m pip wheel -q --no-build-isolation --no-deps -w $(WHEEL_DIR) ./native
	$(PY) -m pip install -q --force-reinstall --no-deps $(WHEEL_DIR)/pcvr_native-*.whl
	touch $@

native: $(VENV)/.native-stamp

# The same module built for CPUs without AVX2 (its scalar paths), unpacked where the native tests
# can import it from; its own build tree keeps both builds incremental.
PORTABLE := build/portable
$(PORTABLE)/.stamp: $(VENV)/.deps-stamp $(NATIVE_SOURCES)
	rm -rf $(PORTABLE) && mkdir -p $(PORTABLE)
	flock native/.build.lock $(PY) -m pip wheel -q --no-build-isolation --no-deps -w $(PORTABLE) ./native \
	  --config-settings=cmake.define.PCVR_ARCH=x86-64 --config-settings=build-dir=build/portable-{wheel_tag}
	$(PY) -m zipfile -e $(PORTABLE)/pcvr_native-*.whl $(PORTABLE)
	touch $@

# The core's C++ unit tests (no OpenVDB, no Python: seconds to build).
UNIT_TESTS := build/native-tests/pcvr_unit_tests
$(UNIT_TESTS): $(NATIVE_SOURCES) $(wildcard native/tests/*) | system
	cmake -S native/tests -B build/native-tests -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
	cmake --build build/native-tests

# The add-on tests install the packaged extension, so the zip is built first.
test: $(VENV)/.native-stamp $(EXTENSION_ZIP) $(PORTABLE)/.stamp $(UNIT_TESTS)
	$(UNIT_TESTS) | tail -1
	$(PY) -m pytest
	@echo "Native and stress tests again, on the build without AVX2:"
	PYTHONPATH=$(PORTABLE) $(PY) -m pytest -q -p no:cacheprovider tests/native tests/stress

# The phantom through the native module (timed, checked against exact), then through Blender's
# PCVR engine by the command line: X-ray, and shaded in Hounsfield units with the CT Bone preset.
demo: $(VENV)/.native-stamp
	$(PY) tools/demo.py --output out/demo_xray.png
	$(PY) -m pcvr_addon render out/phantom.vdb -o out/demo_blender.png --magnification 4
	$(PY) -m pcvr_addon render out/ct_head.vdb -o out/demo_shaded.png --mode shaded --preset "CT Bone" --magnification 3

extension: $(EXTENSION_ZIP)

$(EXTENSION_ZIP): $(VENV)/.native-stamp blender_manifest.toml tools/build_extension.py $(ADDON_SOURCES)
	$(PY) tools/build_extension.py

# The benchmark's own packages: the peers (VTK's wheel renders offscreen through EGL; EEVEE needs an
# OpenGL context, which Mesa's EGL gives without a display) and the analysis (scipy, matplotlib).
# QUICK=1: small volumes and budgets, about 3 minutes.
BENCH_PIP := "vtk>=9.4" scipy matplotlib
BENCH_APT := libegl1 libegl-mesa0 libgl1-mesa-dri
bench: $(VENV)/.native-stamp
	@missing=""; for p in $(BENCH_APT); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing; \
	fi
	$(PY) -m pip install -q $(BENCH_PIP)
	$(PY) tests/bench/run_benchmarks.py --output docs/benchmarks.md $(if $(QUICK),--quick)

clean:
	rm -rf native/build $(WHEEL_DIR) out

# ---------------------------------------------------------------------------------------------------
# Every Blender the manifest claims. .venv has bpy 5.0; the LTS releases before it get a virtual
# environment each (.venv-bpy42, .venv-bpy45) with their bpy and the native wheel that .venv built
# (cp311, the same for all). bpy 4.2 bundles no OpenImageIO Python module, so the package index's
# stands in there. `make test` smoke-tests each (tests/addon/test_blender_versions.py);
# `make test-compat` runs all the add-on tests on each.

COMPAT_BLENDERS := 42 45
BPY_42   := 4.2.23
BPY_45   := 4.5.15
EXTRA_42 := openimageio
COMPAT_STAMPS := $(foreach v,$(COMPAT_BLENDERS),.venv-bpy$(v)/.native-stamp)

.PHONY: test-compat compat-smoke
.SECONDARY: $(foreach v,$(COMPAT_BLENDERS),.venv-bpy$(v)/.deps-stamp)  # stamps to keep, not intermediates

# The Makefile holds the versions: pip runs again when it changes (seconds when nothing is new).
# The scan readers' packages (pcvr_addon/volume_import) as requirements.txt pins them.
SCAN_PACKAGES = $(shell grep -E '^(pydicom|nibabel|pynrrd|tifffile)==' requirements.txt)
.venv-bpy%/.deps-stamp: Makefile requirements.txt | system
	test -x $(@D)/bin/python || $(PYTHON_SYS) -m venv $(@D)
	$(@D)/bin/python -m pip install -q --upgrade pip
	$(@D)/bin/python -m pip install -q bpy==$(BPY_$*) numpy pytest $(EXTRA_$*) $(SCAN_PACKAGES)
	touch $@

.venv-bpy%/.native-stamp: .venv-bpy%/.deps-stamp $(VENV)/.native-stamp
	$(@D)/bin/python -m pip install -q --force-reinstall --no-deps $(WHEEL_DIR)/pcvr_native-*.whl
	touch $@

# Each Blender in turn, all of them even when one fails.
compat_pytest = failed=""; for v in $(COMPAT_BLENDERS); do \
	  echo "bpy $$(.venv-bpy$$v/bin/python -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -1):"; \
	  .venv-bpy$$v/bin/python -m pytest -q -p no:cacheprovider $(1) || failed="$$failed $$v"; \
	done; test -z "$$failed" || { echo "failed on .venv-bpy:$$failed"; exit 1; }

compat-smoke: $(COMPAT_STAMPS)
	@$(call compat_pytest,tests/addon/test_blender_versions.py)

test-compat: $(COMPAT_STAMPS) $(EXTENSION_ZIP)
	@$(call compat_pytest,tests/addon)

test: compat-smoke

# ---- Robustness: make stress, make fuzz, make sanitize (docs/reliability.md) ------------------
.PHONY: stress fuzz sanitize

# The stress suite with more cases, larger volumes and 400 Hypothesis examples per property.
stress: $(VENV)/.native-stamp $(EXTENSION_ZIP)
	PCVR_STRESS=long $(PY) -m pytest -q -p no:cacheprovider tests/stress

# libFuzzer over the core (clang-14 and its runtime from Debian), FUZZ_SECONDS per target (three:
# 10 minutes in all by default), after replaying tests/fuzz_regressions; then the source coverage the
# corpora reach.
FUZZ_SECONDS ?= 200
FUZZ_DIR    := build/fuzz
APT_FUZZ    := clang-14 libclang-rt-14-dev llvm-14
fuzz: $(VENV)/.native-stamp
	@missing=""; for p in $(APT_FUZZ); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing; fi
	for kind in "" "-coverage"; do \
	  CC=clang-14 CXX=clang++-14 cmake -S native -B $(FUZZ_DIR)$$kind -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	    -DPCVR_PYTHON=OFF -DPCVR_FUZZ=ON -DPCVR_COVERAGE=$$([ -n "$$kind" ] && echo ON || echo OFF) > /dev/null && \
	  ninja -C $(FUZZ_DIR)$$kind fuzz_read_vdb fuzz_render fuzz_shaded || exit 1; \
	done
	$(PY) native/fuzz/make_corpus.py $(FUZZ_DIR)/seeds
	native/fuzz/run.sh $(FUZZ_DIR) $(FUZZ_SECONDS)

# The native and stress tests against a module built with AddressSanitizer and
# UndefinedBehaviorSanitizer (gcc; its own build tree). Python itself is not instrumented, so libasan
# is preloaded, and leak checks are off (the interpreter keeps its allocations to the end).
SANITIZE := build/sanitize
$(SANITIZE)/.stamp: $(VENV)/.deps-stamp $(NATIVE_SOURCES)
	rm -rf $(SANITIZE) && mkdir -p $(SANITIZE)
	flock native/.build.lock $(PY) -m pip wheel -q --no-build-isolation --no-deps -w $(SANITIZE) ./native \
	  --config-settings=cmake.define.PCVR_SANITIZE=ON --config-settings=cmake.build-type=RelWithDebInfo \
	  --config-settings=build-dir=build/sanitize-{wheel_tag}
	$(PY) -m zipfile -e $(SANITIZE)/pcvr_native-*.whl $(SANITIZE)
	touch $@

sanitize: $(SANITIZE)/.stamp
	LD_PRELOAD="$$(gcc -print-file-name=libasan.so) $$(gcc -print-file-name=libubsan.so)" \
	ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
	PCVR_SANITIZED=1 PYTHONPATH=$(SANITIZE) $(PY) -m pytest -q -p no:cacheprovider tests/native tests/stress \
	  --deselect tests/native/test_bpy_coexistence.py

# PCVR: `make demo` and `make test` set up everything on a fresh Debian 12 machine.
# Steps are stamped, so a second run with nothing changed installs and rebuilds nothing.

SHELL       := /bin/bash
PYTHON_SYS  ?= python3.11
# Python 3.13, for the cp313 wheel (Blender 5.1 and later) and the bpy 5.2 and 5.3 environments: the
# first of these that runs, or PYTHON313=/path/to/python3.13. It needs its headers (Python.h) and venv.
PYTHON313   ?= $(firstword $(foreach p,python3.13 $(wildcard $(HOME)/.pyenv/versions/3.13*/bin/python3.13),\
                 $(shell $(p) -c 'import sys' >/dev/null 2>&1 && echo $(p))))
VENV        := .venv
PY          := $(VENV)/bin/python
SUDO        := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
APT_PACKAGES := build-essential cmake ninja-build ccache libopenvdb-dev libboost-dev libboost-iostreams-dev libtbb-dev
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

# The wheels Blender loads, one per Python it ships: cp311 (Blender 4.2 to 5.0) and cp313 (5.1 to 5.3).
# Each is built in place (native/build/<tag>, incremental; the lock keeps concurrent builds from sharing a
# build tree) into build/wheels-raw, then made self-contained by auditwheel: the OpenVDB, oneTBB, Boost,
# Blosc... it links are copied into the wheel under hashed names (so they never meet bpy's own libraries of
# the same name), leaving glibc and libstdc++ to the system. Debian 12's libraries need glibc 2.35 and
# GCC 12's libstdc++ (auditwheel show), hence the tag. ccache (when present) compiles the core, which does
# not depend on Python, once for both wheels.
RAW_WHEELS  := build/wheels-raw
MANYLINUX   := manylinux_2_35_x86_64
BUILD_313   := build/python3.13
# Looked for when the recipe runs: `system` may have just installed it.
LAUNCHER    := $$(command -v ccache >/dev/null && echo --config-settings=cmake.define.CMAKE_CXX_COMPILER_LAUNCHER=ccache)
# $(call wheel,PYTHON,TAG): build, repair and stamp the wheel for one interpreter.
define wheel
	rm -f $(RAW_WHEELS)/pcvr_native-*-$(2)-*.whl $(WHEEL_DIR)/pcvr_native-*-$(2)-*.whl
	CCACHE_DIR=$(CURDIR)/build/ccache flock native/.build.lock \
	  $(1) -m pip wheel -q --no-build-isolation --no-deps -w $(RAW_WHEELS) ./native $(LAUNCHER)
	set -o pipefail; PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(PY) -m auditwheel repair --plat $(MANYLINUX) \
	  -w $(WHEEL_DIR) $(RAW_WHEELS)/pcvr_native-*-$(2)-*.whl 2>&1 | tail -1
	touch $@
endef

$(WHEEL_DIR)/.cp311-stamp: $(VENV)/.deps-stamp $(NATIVE_SOURCES)
	$(call wheel,$(PY),cp311)

# After the cp311 wheel, whose core objects ccache then has.
$(WHEEL_DIR)/.cp313-stamp: $(BUILD_313)/.stamp $(VENV)/.deps-stamp $(NATIVE_SOURCES) | $(WHEEL_DIR)/.cp311-stamp
	$(call wheel,$(BUILD_313)/bin/python,cp313)

WHEEL_STAMPS := $(WHEEL_DIR)/.cp311-stamp $(WHEEL_DIR)/.cp313-stamp

# The 3.13 build environment: the same build requirements as .venv's (requirements.txt), nothing else.
$(BUILD_313)/.stamp: requirements.txt | python313
	test -x $(@D)/bin/python || $(PYTHON313) -m venv $(@D)
	$(@D)/bin/python -m pip install -q $$(grep -E '^(scikit-build-core|nanobind)' requirements.txt)
	touch $@

.PHONY: python313
python313:
	@test -n "$(PYTHON313)" || { echo "Python 3.13 not found (tried python3.13 and ~/.pyenv/versions/3.13*):" \
	  "install it (pyenv install 3.13, or python3.13-dev and python3.13-venv where the system has them) or" \
	  "pass PYTHON313=/path/to/python3.13"; exit 1; }
	@$(PYTHON313) -c 'import sysconfig, os, sys, venv; sys.exit(not os.path.exists(sysconfig.get_paths()["include"] + "/Python.h"))' \
	  || { echo "$(PYTHON313) has no Python.h or venv module: install its headers (python3.13-dev)"; exit 1; }

# .venv runs the repaired cp311 wheel: the tests check what ships.
$(VENV)/.native-stamp: $(WHEEL_DIR)/.cp311-stamp
	$(PY) -m pip install -q --force-reinstall --no-deps $(WHEEL_DIR)/pcvr_native-*-cp311-*.whl
	touch $@

native: $(VENV)/.native-stamp

# The same module built for CPUs without AVX2 (its scalar paths), unpacked where the native tests
# can import it from; its own build tree keeps both builds incremental. `make test-no-avx2` runs the native
# and stress tests on it; `make test-compat` does, out of make test's 15 minutes (the wheels Blender loads
# need AVX2, checked before the module loads).
NO_AVX2 := build/no-avx2
$(NO_AVX2)/.stamp: $(VENV)/.deps-stamp $(NATIVE_SOURCES)
	rm -rf $(NO_AVX2) && mkdir -p $(NO_AVX2)
	flock native/.build.lock $(PY) -m pip wheel -q --no-build-isolation --no-deps -w $(NO_AVX2) ./native \
	  --config-settings=cmake.define.PCVR_ARCH=x86-64 --config-settings=build-dir=build/no-avx2-{wheel_tag}
	$(PY) -m zipfile -e $(NO_AVX2)/pcvr_native-*.whl $(NO_AVX2)
	touch $@

.PHONY: test-no-avx2
test-no-avx2: $(NO_AVX2)/.stamp
	PYTHONPATH=$(NO_AVX2) $(PY) -m pytest -q -p no:cacheprovider tests/native tests/stress

# The core's C++ unit tests (no OpenVDB, no Python: seconds to build).
UNIT_TESTS := build/native-tests/pcvr_unit_tests
$(UNIT_TESTS): $(NATIVE_SOURCES) $(wildcard native/tests/*) | system
	cmake -S native/tests -B build/native-tests -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
	cmake --build build/native-tests

# The add-on tests install the packaged extension, so the zip is built first.
test: $(VENV)/.native-stamp $(EXTENSION_ZIP) $(UNIT_TESTS)
	$(UNIT_TESTS) | tail -1
	$(PY) -m pytest

# The phantom through the native module (timed, checked against exact), then through Blender's
# PCVR engine by the command line: X-ray, and shaded in Hounsfield units with the CT Bone preset.
demo: $(VENV)/.native-stamp
	$(PY) tools/demo.py --output out/demo_xray.png
	$(PY) -m pcvr_addon render out/phantom.vdb -o out/demo_blender.png --magnification 4
	$(PY) -m pcvr_addon render out/ct_head.vdb -o out/demo_shaded.png --mode shaded --preset "CT Bone" --magnification 3

extension: $(EXTENSION_ZIP)

$(EXTENSION_ZIP): $(VENV)/.native-stamp $(WHEEL_STAMPS) blender_manifest.toml extension_requirements.txt \
                  tools/build_extension.py $(ADDON_SOURCES)
	$(PY) tools/build_extension.py

# The benchmark's own packages: the peers (VTK's wheel renders offscreen through EGL; EEVEE needs an
# OpenGL context, which Mesa's EGL gives without a display; DRRs beside plastimatch and RTK's Joseph
# projector) and the analysis (scipy, matplotlib). QUICK=1: small volumes and budgets, about 3 minutes.
BENCH_PIP := "vtk>=9.4" scipy matplotlib itk-rtk
BENCH_APT := libegl1 libegl-mesa0 libgl1-mesa-dri plastimatch
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
	rm -rf native/build $(WHEEL_DIR) $(RAW_WHEELS) out

# ---------------------------------------------------------------------------------------------------
# Every Blender the manifest claims. .venv has bpy 5.0; the LTS releases and the newest get a virtual
# environment each (.venv-bpy42, ...) with their bpy, on the Python that Blender ships, and the wheel
# built for it. bpy 4.2 bundles no OpenImageIO Python module, so the package index's stands in there.
# `make test` smoke-tests the oldest and the newest (tests/addon/test_blender_versions.py): 4.5 takes 4.2's
# Python and wheel, and its environment and smoke test (2 minutes from a fresh clone) would take `make
# test` past 15 minutes on a new 2-core machine. `make test-compat` runs all the add-on tests on each,
# with Blender's deprecation warnings made errors.

COMPAT_BLENDERS := 42 45 52 53
SMOKE_BLENDERS  ?= 42 53
BPY_42   := 4.2.23
BPY_45   := 4.5.15
BPY_52   := 5.2.3
BPY_53   := 5.3.0
EXTRA_42 := openimageio
# The wheel each one loads: Blender 4.2 to 5.0 ship Python 3.11, 5.1 and later 3.13.
PYTAG_42 := cp311
PYTAG_45 := cp311
PYTAG_52 := cp313
PYTAG_53 := cp313
python_for = $(if $(filter cp313,$(PYTAG_$(1))),$(PYTHON313),$(PYTHON_SYS))
# Blender's own deprecation warnings (RNA properties: "'Scene.x' is expected to be removed in Blender 6.0"),
# as an ini filter: pytest's -W takes the message literally, and Blender's start with the property's name.
BLENDER_DEPRECATIONS := -o "filterwarnings=error:.*is expected to be removed:DeprecationWarning"

.PHONY: test-compat compat-smoke
.SECONDARY: $(foreach v,$(COMPAT_BLENDERS),.venv-bpy$(v)/.deps-stamp)  # stamps to keep, not intermediates

# The Makefile holds the versions: pip runs again when it changes (seconds when nothing is new).
# The scan readers' packages (pcvr_addon/volume_import) as requirements.txt pins them.
SCAN_PACKAGES = $(shell grep -E '^(pydicom|nibabel|pynrrd|tifffile)==' requirements.txt)
.venv-bpy%/.deps-stamp: Makefile requirements.txt | system python313
	test -x $(@D)/bin/python || $(call python_for,$*) -m venv $(@D)
	$(@D)/bin/python -m pip install -q --upgrade pip
	$(@D)/bin/python -m pip install -q bpy==$(BPY_$*) numpy pytest $(EXTRA_$*) $(SCAN_PACKAGES)
	touch $@

.SECONDEXPANSION:
.venv-bpy%/.native-stamp: .venv-bpy%/.deps-stamp $(WHEEL_DIR)/.$$(PYTAG_$$*)-stamp
	$(@D)/bin/python -m pip install -q --force-reinstall --no-deps $(WHEEL_DIR)/pcvr_native-*-$(PYTAG_$*)-*.whl
	touch $@

# $(call compat_pytest,BLENDERS,TESTS): each Blender in turn, all of them even when one fails.
compat_pytest = failed=""; for v in $(1); do \
	  echo "bpy $$(.venv-bpy$$v/bin/python -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -1):"; \
	  .venv-bpy$$v/bin/python -m pytest -q -p no:cacheprovider $(BLENDER_DEPRECATIONS) $(2) || failed="$$failed $$v"; \
	done; test -z "$$failed" || { echo "failed on .venv-bpy:$$failed"; exit 1; }

compat-smoke: $(foreach v,$(SMOKE_BLENDERS),.venv-bpy$(v)/.native-stamp)
	@$(call compat_pytest,$(SMOKE_BLENDERS),tests/addon/test_blender_versions.py)

test-compat: $(foreach v,$(COMPAT_BLENDERS),.venv-bpy$(v)/.native-stamp) $(EXTENSION_ZIP)
	@$(call compat_pytest,$(COMPAT_BLENDERS),tests/addon)
	$(MAKE) --no-print-directory test-portable
	$(MAKE) --no-print-directory test-no-avx2

test: compat-smoke

# ---- A root file system without the build machine's libraries (make test-portable) ---------------
# Debian 13 (glibc 2.41, Python 3.13), made by debootstrap with only what bpy itself links (X11, GL),
# and a virtual environment with the newest bpy from the wheels .venv-bpy53 has (downloaded here: no
# network inside). Kept in build/ (1.6 GB, 4 to 5 minutes the first time), made again only when the
# script or the bpy version changes. tests/portable installs the extension zip there as Blender does
# and renders through F12 and the command line, then compares the images with the same renders here.
PORTABLE_ROOT   := build/debian13-root
PORTABLE_PYTHON := .venv-bpy53
PORTABLE_STAMP  := $(PORTABLE_ROOT)/.stamp-bpy$(BPY_53)

$(PORTABLE_STAMP): tools/portable_root.sh | root-user $(PORTABLE_PYTHON)/.deps-stamp
	@command -v debootstrap >/dev/null || { apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap; }
	rm -rf build/portable-wheels && mkdir -p build/portable-wheels
	$(PORTABLE_PYTHON)/bin/python -m pip freeze --exclude pcvr_native > build/portable-wheels/requirements.txt
	$(PORTABLE_PYTHON)/bin/python -m pip download -q --only-binary=:all: --no-deps -d build/portable-wheels \
	  -r build/portable-wheels/requirements.txt
	tools/portable_root.sh create $(PORTABLE_ROOT) build/portable-wheels
	touch $(PORTABLE_ROOT)/.stamp $@

.PHONY: test-portable root-user
root-user:
	@[ "$$(id -u)" = 0 ] || { echo "make test-portable runs as root (debootstrap, chroot): sudo make test-portable"; exit 1; }

test-portable: root-user $(PORTABLE_STAMP) $(PORTABLE_PYTHON)/.native-stamp $(EXTENSION_ZIP)
	PCVR_PORTABLE_ROOT=$(PORTABLE_ROOT) $(PORTABLE_PYTHON)/bin/python -m pytest -q -p no:cacheprovider \
	  $(BLENDER_DEPRECATIONS) tests/portable

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

# atlasgen: set-up, demo, tests and benchmarks. `make demo` and `make test` work on a fresh Debian 12.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
ATLASGEN := $(VENV)/bin/atlasgen
BUILD := build
# Debian packages: LLVM >= 16 for Mitsuba's llvm variants, lavapipe for wgpu, and EGL/GL for completeness.
APT_PACKAGES := libllvm19 mesa-vulkan-drivers libegl1 libegl-mesa0 libgl1-mesa-dri
export XDG_RUNTIME_DIR ?= /tmp/atlasgen-xdg-$(shell id -u)

.PHONY: setup apt demo test bench clean atlas

setup: apt $(VENV)/.stamp

# Installs only what is missing, as root via apt-get (sudo where we are not root).
apt:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(VENV)/.stamp: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -e '.[mitsuba,render,report,test]'
	touch $@

demo: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(ATLASGEN) bake materials -o $(BUILD)/atlas.dds --preview $(BUILD)/atlas-preview.png

test: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) -m pytest -q

bench: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) bench/run.py

clean:
	rm -rf $(BUILD) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +

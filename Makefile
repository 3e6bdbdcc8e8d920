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

.PHONY: setup apt demo test bench clean atlas FORCE

# ---- incremental content pipeline -------------------------------------------------------------
# Each material file bakes into its own cache entry (build/cache/<stem>.npz); the atlas is then
# assembled from the cache. Only materials whose file, or whose bake code, changed are re-baked,
# every write is atomic, and no two jobs write the same file, so `make -j2 atlas` is safe.
MATERIAL_FILES := $(sort $(wildcard materials/*.toml))
CACHE_DIR := $(BUILD)/cache
CACHED := $(patsubst materials/%.toml,$(CACHE_DIR)/%.npz,$(MATERIAL_FILES))
BAKE_CODE := $(sort $(wildcard atlasgen/models/*.py atlasgen/separable/*.py)) atlasgen/params.py atlasgen/contract.py atlasgen/adaptive.py
ASSEMBLY_CODE := $(sort $(wildcard atlasgen/*.py))

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

atlas: $(BUILD)/atlas.dds

# Rewritten only when the set of material files changes, so removing one re-assembles the atlas.
$(BUILD)/materials.list: FORCE
	@mkdir -p $(BUILD); echo "$(MATERIAL_FILES)" | cmp -s - $@ || echo "$(MATERIAL_FILES)" > $@

$(CACHE_DIR)/%.npz: materials/%.toml $(BAKE_CODE) | $(VENV)/.stamp
	$(ATLASGEN) bake $< --cache $(CACHE_DIR) --cache-only -q

$(BUILD)/atlas.dds: $(CACHED) $(BUILD)/materials.list $(ASSEMBLY_CODE) | $(VENV)/.stamp
	$(ATLASGEN) bake $(MATERIAL_FILES) --cache $(CACHE_DIR) -o $@ --preview $(BUILD)/atlas-preview.png

demo: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(MAKE) atlas

test: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) -m pytest -q

bench: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) bench/run.py

clean:
	rm -rf $(BUILD) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +

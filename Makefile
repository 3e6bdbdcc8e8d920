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

.PHONY: setup apt demo test bench clean atlas render validate report FORCE

# ---- incremental content pipeline -------------------------------------------------------------
# Each material file bakes into its own cache entry (build/cache/<stem>.npz); the atlas is then
# assembled from the cache. Only materials whose file, or whose bake code, changed are re-baked,
# every write is atomic, and no two jobs write the same file, so `make -j2 atlas` is safe.
MATERIAL_FILES := $(sort $(wildcard materials/*.toml))
CACHE_DIR := $(BUILD)/cache
CACHED := $(patsubst materials/%.toml,$(CACHE_DIR)/%.npz,$(MATERIAL_FILES))
BAKE_CODE := $(sort $(wildcard atlasgen/models/*.py atlasgen/separable/*.py)) atlasgen/params.py atlasgen/contract.py atlasgen/adaptive.py
ASSEMBLY_CODE := $(sort $(wildcard atlasgen/*.py))
SEPARABLE_FILES := $(sort $(wildcard materials/separable-*.toml))
RENDER_CODE := $(sort $(wildcard atlasgen/render/*.py atlasgen/shaders/*.wgsl))
VALIDATE_CODE := $(sort $(wildcard atlasgen/validate/*.py scenes/validation/*.toml)) $(RENDER_CODE)

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

# Each of these re-runs only when its inputs change; every writer is atomic.
render: $(BUILD)/demo.png
$(BUILD)/demo.png: scenes/demo.toml $(wildcard scenes/meshes/*) $(BUILD)/atlas.dds $(RENDER_CODE) | $(VENV)/.stamp
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(ATLASGEN) render scenes/demo.toml --atlas $(BUILD)/atlas.dds -o $(BUILD)/demo.exr

validate: $(BUILD)/validation/report.json
$(BUILD)/validation/report.json: $(BUILD)/atlas.dds $(VALIDATE_CODE) | $(VENV)/.stamp
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(ATLASGEN) validate --atlas $(BUILD)/atlas.dds -o $(BUILD)/validation -q

$(BUILD)/report/separable/index.md: $(SEPARABLE_FILES) $(BUILD)/atlas.dds $(BAKE_CODE) | $(VENV)/.stamp
	$(ATLASGEN) report separable $(SEPARABLE_FILES) --atlas $(BUILD)/atlas.dds -o $(BUILD)/report/separable

report: $(BUILD)/report/index.html
$(BUILD)/report/index.html: $(BUILD)/atlas.dds $(BUILD)/report/separable/index.md $(wildcard $(BUILD)/validation/report.json) | $(VENV)/.stamp
	$(ATLASGEN) report library --atlas $(BUILD)/atlas.dds --validation $(BUILD)/validation --separable $(BUILD)/report/separable -o $(BUILD)/report

demo: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(MAKE) atlas
	$(MAKE) render
	$(MAKE) validate
	$(MAKE) report
	@echo "demo: build/atlas.dds, build/atlas-preview.png, build/demo.png, build/validation/index.html, build/report/index.html"

test: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) -m pytest -q

bench: setup
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 700 $(XDG_RUNTIME_DIR)
	$(PY) bench/run.py

clean:
	rm -rf $(BUILD) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +

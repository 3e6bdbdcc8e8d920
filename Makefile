# atlasgen: set-up, demo, tests and benchmarks. `make demo` and `make test` work on a fresh Debian 12.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
ATLASGEN := $(VENV)/bin/atlasgen
BUILD := build
# Debian packages: LLVM >= 16 for Mitsuba's llvm variants, lavapipe for wgpu, EGL/GL for completeness,
# glslang (glslangValidator) to compile the GLSL and HLSL includes in the tests, and headless
# Chromium with its driver for the reports' browser test (tests/reports/test_browser.py).
APT_PACKAGES := libllvm19 mesa-vulkan-drivers libegl1 libegl-mesa0 libgl1-mesa-dri glslang-tools chromium chromium-driver
export XDG_RUNTIME_DIR ?= /tmp/atlasgen-xdg-$(shell id -u)

.PHONY: setup apt demo test lint fuzz bench bench-workflow device-prepare clean atlas render validate report pins tags

# ---- incremental content pipeline -------------------------------------------------------------
# Each material file bakes into its own cache entry (build/cache/<stem>.npz); the atlas is then
# assembled from the cache. Only materials whose file, or whose bake code, changed are re-baked,
# every write is atomic, and no two jobs write the same file, so `make -j2 atlas` is safe.
# Validation and the separable report follow the same pattern: one job per material, into its own
# folder, re-run only when that material's bake result or the code that measures it changed, then
# a cheap merge that reads the per-material JSON and renders or measures nothing.
# A MaterialX document (materials/*.mtlx) bakes each of its materials into its own cache entry
# (build/cache/<stem>.mtlx/<material>.npz), which make cannot name before reading the document: the
# document's stamp (build/cache/<stem>.mtlx.stamp) stands for them, and its validation is one job.
# make splits file names on spaces, so "scenes/toon stage.toml" was two words: sha256sum errors on every make, a junk
# hash, "No rule to make target" for render and a material left out of the atlas without a word. A colon or a percent
# sign broke the Makefile itself ("target pattern contains no '%'"), a quote the shell's recipes (syntax errors), a
# dollar sign the name ("materials/cost.toml: no such file"). The shell's own characters went into the recipes as they
# are: "a>b.toml" emptied a file b.toml, "a&b.toml" ran half a bake in the background, a bracket or a backquote was a
# syntax error, a tab or a line break another name. Refused on one line.
HASH := \#
UNNAMEABLE_PATTERNS := -name '* *' -o -name '*:*' -o -name '*%*' -o -name "*'*" -o -name '*"*' -o -name '*$$*' -o -name '*\#*' \
	-o -name '*;*' -o -name '*\\*' -o -name '*[[*?]*' -o -name '*[<>|&()`{}]*' -o -name '*[[:cntrl:]]*'
UNNAMEABLE_FILES := $(shell find materials scenes -maxdepth 1 \( $(UNNAMEABLE_PATTERNS) \) \( -name '*.toml' -o -name '*.mtlx' \) 2>/dev/null \
	| LC_ALL=C sed 's/[[:cntrl:]]/?/g')
ifneq ($(UNNAMEABLE_FILES),)
ifeq ($(filter clean setup apt,$(MAKECMDGOALS)),)
$(error $(UNNAMEABLE_FILES): a file name with a space, a control character or one of : % ' " $$ $(HASH) ; \ * ? [ < > | & ( ) ` { }, which make cannot name; expected names without them (rename it; atlasgen itself reads it as it is))
endif
endif
# A folder named as a material or scene file (materials/glaze.toml/) was globbed as one: make ended 0 with grep's and
# sha256sum's "Is a directory", baked the folder's own files into the atlas without a word, and never settled.
NOT_FILES := $(shell find materials scenes -maxdepth 1 -mindepth 1 \( -name '*.toml' -o -name '*.mtlx' \) ! -type f \
	! \( -type l -xtype f \) 2>/dev/null | LC_ALL=C sed 's/[[:cntrl:]]/?/g')
ifneq ($(NOT_FILES),)
ifeq ($(filter clean setup apt,$(MAKECMDGOALS)),)
$(error $(NOT_FILES): a folder, a dangling link or another file that is no regular file, named as a material or scene file; expected a file (rename or remove it))
endif
endif
TOML_FILES := $(sort $(wildcard materials/*.toml))
MTLX_FILES := $(sort $(wildcard materials/*.mtlx))
MATERIAL_FILES := $(TOML_FILES) $(MTLX_FILES)
STEMS := $(patsubst materials/%.toml,%,$(TOML_FILES))
MTLX_STEMS := $(patsubst materials/%.mtlx,%,$(MTLX_FILES))
CACHE_DIR := $(BUILD)/cache
CACHED := $(patsubst %,$(CACHE_DIR)/%.npz,$(STEMS)) $(patsubst %,$(CACHE_DIR)/%.mtlx.stamp,$(MTLX_STEMS))
# Every file the bake always writes, as one grouped target: one deleted (build/atlas.json) re-assembles,
# where only atlas.dds was a target and make saw nothing to do. (atlas.separable.bin is written only
# for separable materials, so it is not one of them.)
# What every bake writes beside its atlas (-o X.dds), the library's and each scene's.
BAKE_SUFFIXES := .dds .json .wgsl .glsl .hlsl .timings.json
ATLAS_SET := $(addprefix $(BUILD)/atlas,$(BAKE_SUFFIXES) -preview.png)
# What the jobs that read the library's atlas wait for: the texture and its manifest (--ids-from and --atlas read both).
# Asking for atlas.dds alone left a deleted atlas.json missing (make checks only the member it is asked for), and
# the scene bakes failed on it.
LIBRARY_ATLAS := $(BUILD)/atlas.dds $(BUILD)/atlas.json
# Code lists follow the package layers (tests/test_layers.py). The cache key hashes every layer
# below bake/ plus the supersampling (atlasgen/bake/cache.py BAKE_RELEVANT; a test checks they
# agree); __init__.py holds the version, which is part of every key.
BELOW_BAKE := $(sort $(wildcard atlasgen/*.py $(foreach layer,optics io separable shaders models materials,atlasgen/$(layer)/*.py)))
BAKE_CODE := $(BELOW_BAKE) atlasgen/bake/adaptive.py
# Assembling the atlas from cached slices: everything up to and including bake/.
ASSEMBLY_CODE := $(BELOW_BAKE) $(sort $(wildcard atlasgen/bake/*.py))
# What lies between a material's cached float slices and what is measured of them: encoding,
# mips, DDS/KTX2, the include, reading the atlas back and the CPU sampler: the same layers.
SLICE_CODE := $(ASSEMBLY_CODE)
REPORT_CODE := $(sort $(wildcard atlasgen/reports/*.py atlasgen/reports/templates/*))
# Separable materials by their type, read with grep so that parsing the Makefile stays instant.
SEPARABLE_FILES := $(sort $(if $(TOML_FILES),$(shell grep -lE '^[[:space:]]*type[[:space:]]*=[[:space:]]*["'"'"']separable["'"'"']' $(TOML_FILES))))
SEPARABLE_STEMS := $(patsubst materials/%.toml,%,$(SEPARABLE_FILES))
RENDER_CODE := $(sort $(wildcard atlasgen/render/*.py atlasgen/shaders/*.wgsl))
VALIDATE_CODE := $(sort $(wildcard atlasgen/validate/*.py atlasgen/data/validation/*.toml)) $(RENDER_CODE) $(REPORT_CODE)
VALIDATION := $(BUILD)/validation
VALIDATED := $(patsubst %,$(VALIDATION)/materials/%/report.json,$(STEMS))
# A document's folder apart from the TOML files': a.mtlx beside a.toml were one target with two recipes.
MTLX_VALIDATED := $(patsubst %,$(VALIDATION)/documents/%/report.json,$(MTLX_STEMS))
SEPARABLE_REPORT := $(BUILD)/report/separable
SEPARABLE_STUDIES := $(patsubst %,$(SEPARABLE_REPORT)/materials/%/report.json,$(SEPARABLE_STEMS))

# The three.js example's JavaScript (web/package.json, pinned exactly by web/package-lock.json), for
# tests/web/test_threejs.py: `npm ci` when node_modules is missing or the lock changed (npm ci writes
# node_modules/.package-lock.json). Without npm the browser test skips, so set-up only says so.
WEB_DEPS := web/node_modules/.package-lock.json
setup: apt $(VENV)/.stamp $(BUILD)/versions.txt $(WEB_DEPS)

$(WEB_DEPS): web/package.json web/package-lock.json
	@if command -v npm >/dev/null 2>&1; then cd web && npm ci --no-audit --no-fund --loglevel=error; \
	else echo "npm not found: web/node_modules not installed (tests/web/test_threejs.py will skip)"; fi

# Installs only what is missing, as root via apt-get (sudo where we are not root).
apt:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

# Every Python package, direct or transitive, is installed at the version constraints.txt pins: the
# goldens' bytes and the reports' figures depend on Mitsuba, Dr.Jit, NumPy and the rest (README,
# Development: "Pinned versions").
EXTRAS := mitsuba,materialx,render,report,test,dev
$(VENV)/.stamp: pyproject.toml $(wildcard constraints.txt)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -c constraints.txt -e '.[$(EXTRAS)]'
	touch $@

# What this set-up runs with: the Python packages (pip freeze) and the Debian packages that decide
# numbers (LLVM for Dr.Jit's JIT, Mesa's lavapipe, glslang). .ci/run prints it.
$(BUILD)/versions.txt: $(VENV)/.stamp
	@mkdir -p $(@D)
	@{ echo "# $$($(PY) --version)"; $(PY) -m pip freeze --all --exclude-editable --disable-pip-version-check; \
	  dpkg-query -W -f '# debian $${Package}=$${Version}\n' $(APT_PACKAGES) 2>/dev/null || true; } > $@.tmp && mv -f $@.tmp $@

# Moves every pin to the newest release that pyproject.toml allows, re-installs through the new
# pins and regenerates the goldens, in one step. Review `git diff constraints.txt tests/resources`
# and say in the commit why the bytes moved.
# The release tags, from the line CHANGELOG.md records them on ("<!-- Tags: v0.1.0 is 5b33261, ..."): a
# clone that arrived without tags gets them back, and the CHANGELOG's compare links resolve.
tags:
	@sed -n 's/^<!-- Tags: \(.*\)\. Relative.*/\1/p' CHANGELOG.md | tr ',' '\n' | \
	while read -r tag _is commit; do git tag -f "$$tag" "$$commit" >/dev/null && echo "$$tag -> $$commit"; done

pins: apt
	rm -rf $(BUILD)/pins-venv && $(PYTHON) -m venv $(BUILD)/pins-venv
	$(BUILD)/pins-venv/bin/pip install -q --disable-pip-version-check -U pip '.[$(EXTRAS)]'
	{ sed -n '/^#/p' constraints.txt; $(BUILD)/pins-venv/bin/pip freeze --all --exclude-editable --disable-pip-version-check \
	  | grep -v -e '^pip==' -e '^atlasgen[= @]'; } > constraints.txt.tmp && mv -f constraints.txt.tmp constraints.txt
	rm -rf $(BUILD)/pins-venv $(VENV) && $(MAKE) setup
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	ATLASGEN_REGENERATE_GOLDEN=1 $(PY) -m pytest -q -n 0 tests/test_golden.py tests/io/test_ktx2.py

atlas: $(ATLAS_SET)

# Rewritten only when the set of material files changes, so removing one re-assembles the atlas
# and re-merges the reports. It is refreshed while the Makefile is read, not by a rule that always
# runs, so that `make -n` and `make -q` report exactly what is out of date.
# $(call write_if_changed,TEXT,FILE): replace FILE atomically with TEXT, only when it says otherwise,
# so that its time stamp moves exactly when its content does. Shell built-ins only, unless FILE changes: each
# `make` reads the Makefile, and a mkdir and a cmp per file were most of a no-op make's 0.27 s (94 processes).
write_if_changed = $(call write_line_if_changed,$(1),$(2),$(dir $(2)))
# $(call write_line_if_changed,TEXT,FILE,FOLDER), for a shell loop, where FILE and FOLDER are shell words.
write_line_if_changed = { [ -d "$(3)" ] || mkdir -p "$(3)"; } && { { IFS= read -r old < "$(2)"; } 2>/dev/null && \
	[ "$$old" = "$(1)" ] || { echo "$(1)" > "$(2).$$$$" && mv -f "$(2).$$$$" "$(2)"; }; }
ifeq ($(filter clean,$(MAKECMDGOALS)),)
$(shell $(call write_if_changed,$(MATERIAL_FILES),$(BUILD)/materials.list))
endif
# Only for `make clean <target>`, where the file is not refreshed while the Makefile is read.
$(BUILD)/materials.list:
	@mkdir -p $(@D) && echo "$(MATERIAL_FILES)" > $@

# build/hashes/<file>.sha256: each material and scene file's content hash, rewritten only when the content changes.
# Its time stamp moves with the content, not the file's: two files swapped by renaming (every name and
# time stamp kept) or an older file copied in with its time (cp -p, rsync -a, tar) re-bake. The files they name
# (meshes, images, measured data) are followed by time stamp alone, as their depfiles name them (README, `make render`).
HASH_DIR := $(BUILD)/hashes
# Scene files too (scenes/*.toml): a scene swapped in with an older time stamp re-bakes and re-renders.
HASHED_FILES := $(MATERIAL_FILES) $(sort $(wildcard scenes/*.toml))
ifeq ($(filter clean,$(MAKECMDGOALS)),)
ifneq ($(HASHED_FILES),)
# One sha256sum and one shell for every file (a file make cannot name is refused above).
$(shell sha256sum $(HASHED_FILES) | while read -r sum name; do f=$(HASH_DIR)/$$name.sha256; \
	$(call write_line_if_changed,$$sum,$$f,$${f%/*}); done)
endif
endif
# A material a scene's depfile still names after it was deleted reaches here too: no hash then (an empty one
# was left before, under sha256sum's own line), and the bake that reads it says what is missing, on one line.
$(HASH_DIR)/%.sha256: %
	@mkdir -p $(@D) && if [ -e $< ]; then sha256sum $< | cut -c1-64 > $@.tmp && mv -f $@.tmp $@; fi
# Not intermediates: in `make clean atlas` the rule above makes them (nothing writes them while the Makefile is
# read), and make deleted them at the end, so the next make wrote them anew and re-baked every material.
.SECONDARY: $(foreach f,$(HASHED_FILES),$(HASH_DIR)/$(f).sha256)
# `make -j2 clean atlas` ran clean beside the first bakes, which then left stale materials behind.
ifneq ($(filter clean,$(MAKECMDGOALS)),)
.NOTPARALLEL:
endif

# Static pattern rules, for the library's materials only: a scene's depfile still naming a renamed material's file and
# cache entry makes both targets (gcc -MP), and a plain pattern rule then took the entry for one to remake from the
# file that is gone ("no such file" on every make); without a rule the scene simply re-bakes.
# The bake also writes build/cache/<stem>.d, which makes the entry depend on the files the material names (a measured
# BSDF's data, a bitmap): a changed data file re-bakes it. An entry whose depfile is gone is baked again.
-include $(patsubst %,$(CACHE_DIR)/%.d,$(STEMS))
TOML_WITHOUT_DEPFILE := $(foreach s,$(STEMS),$(if $(wildcard $(CACHE_DIR)/$(s).npz),$(if $(wildcard $(CACHE_DIR)/$(s).d),,$(CACHE_DIR)/$(s).npz)))
$(TOML_WITHOUT_DEPFILE): no-depfile
$(filter %.npz,$(CACHED)): $(CACHE_DIR)/%.npz: materials/%.toml $(HASH_DIR)/materials/%.toml.sha256 $(BAKE_CODE) | $(VENV)/.stamp
	$(ATLASGEN) bake $< --cache $(CACHE_DIR) --cache-only --depfile $(CACHE_DIR)/$*.d --depfile-target $@ -q

# The bake also writes build/cache/<stem>.mtlx.d, which makes the stamp depend on the files the
# document includes (xi:include) as well.
-include $(patsubst %,$(CACHE_DIR)/%.mtlx.d,$(MTLX_STEMS))
# A document's stamp whose depfile is gone: make no longer knows the files it includes, so it is baked again (as
# a scene atlas without its depfile is, below), which writes the depfile.
MTLX_WITHOUT_DEPFILE := $(foreach s,$(MTLX_STEMS),$(if $(wildcard $(CACHE_DIR)/$(s).mtlx.stamp),$(if $(wildcard $(CACHE_DIR)/$(s).mtlx.d),,$(CACHE_DIR)/$(s).mtlx.stamp)))
$(MTLX_WITHOUT_DEPFILE): no-depfile
$(filter %.mtlx.stamp,$(CACHED)): $(CACHE_DIR)/%.mtlx.stamp: materials/%.mtlx $(HASH_DIR)/materials/%.mtlx.sha256 $(BAKE_CODE) | $(VENV)/.stamp
	$(ATLASGEN) bake $< --cache $(CACHE_DIR) --cache-only --depfile $(@:.stamp=.d) --depfile-target $@ -q && touch $@

# The bake command's own defaults (--include, --layout) live in the CLI: a change to them re-assembles.
BAKE_COMMAND := $(wildcard cli/main.py cli/options.py)
$(ATLAS_SET) &: $(CACHED) $(BUILD)/materials.list $(ASSEMBLY_CODE) $(BAKE_COMMAND) | $(VENV)/.stamp
	$(ATLASGEN) bake $(MATERIAL_FILES) --cache $(CACHE_DIR) -o $(BUILD)/atlas.dds --preview $(BUILD)/atlas-preview.png

# ---- scenes: each renders from its own atlas, holding only the materials it uses -------------
# build/scenes/X.dds is assembled from the cache with the library's slice IDs (--ids-from), so a
# material has the same ID in every atlas. The bake also writes build/scenes/X.d, which makes
# X.dds depend on the files and cache entries of exactly the scene's materials: a change to a
# material the scene does not use re-bakes and re-renders nothing here.
SCENE_FILES := $(sort $(wildcard scenes/*.toml))
SCENE_ATLASES := $(patsubst scenes/%.toml,$(BUILD)/scenes/%.dds,$(SCENE_FILES))
SCENE_IMAGES := $(SCENE_ATLASES:.dds=.png)
# Every file a scene's bake always writes, one set per scene: a deleted build/scenes/X.json re-bakes
# the set, where only X.dds was a target and the render failed on the missing manifest.
SCENE_SETS := $(foreach a,$(SCENE_ATLASES),$(addprefix $(a:.dds=),$(BAKE_SUFFIXES)))
-include $(SCENE_ATLASES:.dds=.d)
# A scene atlas whose depfile is gone: make no longer knows which materials it holds, so a change to
# one of them would leave it stale. It is baked again, which writes the depfile. (The depfile cannot
# be a target itself: make would then bake scenes to remake it while reading the Makefile, for any goal.)
SCENES_WITHOUT_DEPFILE := $(foreach a,$(SCENE_ATLASES),$(if $(wildcard $(a)),$(if $(wildcard $(a:.dds=.d)),,$(a))))
.PHONY: no-depfile
$(SCENES_WITHOUT_DEPFILE): no-depfile
# The library's manifest is what keeps its IDs (atlasgen/bake/slots.py); deleted, as slots.py's refusals suggest to
# re-number, the library is assembled afresh and its materials may get other slices, while the scene atlases, which
# wait for the library only as order, kept their old IDs and make said all was up to date. Each is baked again.
LIBRARY_IDS_GONE := $(if $(wildcard $(BUILD)/atlas.json),,$(wildcard $(SCENE_ATLASES)))
$(LIBRARY_IDS_GONE): no-depfile
# A manifest naming a separable material has the side-car X.separable.bin beside it, which no rule can name (a bake
# writes it only then): one deleted was never written again, and make said all was up to date. Its set is baked again.
sidecar_gone = $(foreach a,$(1),$(if $(wildcard $(a:.dds=.separable.bin)),,$(if $(wildcard $(a:.dds=.json)),$(if \
	$(shell grep -l '"type": "separable"' $(a:.dds=.json) 2>/dev/null),$(a)))))
SIDECARS_GONE := $(call sidecar_gone,$(BUILD)/atlas.dds $(SCENE_ATLASES))
$(SIDECARS_GONE): no-depfile

# A pattern rule with several targets makes one set: one recipe writes them all.
$(addprefix $(BUILD)/scenes/%,$(BAKE_SUFFIXES)) &: scenes/%.toml $(HASH_DIR)/scenes/%.toml.sha256 $(ASSEMBLY_CODE) $(BAKE_COMMAND) | $(LIBRARY_ATLAS) $(VENV)/.stamp
	$(ATLASGEN) bake $(MATERIAL_FILES) --scene $< --cache $(CACHE_DIR) --ids-from $(BUILD)/atlas.json --depfile $(BUILD)/scenes/$*.d -o $(BUILD)/scenes/$*.dds -q

# A render writes the EXR and its PNG as one set: one target pair, so that a deleted EXR is rendered again. With
# them it writes build/scenes/X.png.d, which makes the image depend on every file the render read: the meshes and
# the environment image the scene names, wherever they are, and only those (a mesh another scene uses re-renders
# nothing here). An image whose depfile is gone is rendered again, as a scene atlas is.
SCENE_EXRS := $(SCENE_IMAGES:.png=.exr)
RENDER_COMMAND := $(wildcard cli/render_cmd.py cli/main.py cli/options.py)
-include $(SCENE_IMAGES:.png=.png.d)
RENDERS_WITHOUT_DEPFILE := $(foreach i,$(SCENE_IMAGES),$(if $(wildcard $(i)),$(if $(wildcard $(i).d),,$(i))))
$(RENDERS_WITHOUT_DEPFILE): no-depfile
# A scene file deleted or renamed left its atlas set and images behind, read as current by whoever lists
# build/scenes/. Each set's files are links into its store, build/scenes/.K.atlasgen, K the name up to its first dot
# (atlasgen/io/atomic.py set_key: scenes toon and toon.night share .toon.atlasgen). A link into a store whose name is
# no current scene's output goes; then a store no current scene's K names; nothing else in the folder is touched. The
# stamp build/scenes/.pruned runs it after every scene's jobs (so nothing is writing there) and when
# build/scenes.list (the scenes, rewritten only when they change) does: a phony render with a recipe would never be
# up to date for make -q.
SCENE_STEMS := $(patsubst scenes/%.toml,%,$(SCENE_FILES))
SCENE_OUTPUTS := $(foreach s,$(SCENE_STEMS),$(addprefix $(s),$(BAKE_SUFFIXES) .separable.bin .d .exr .png .png.d))
SCENE_STORES := $(sort $(foreach s,$(SCENE_STEMS),.$(firstword $(subst ., ,$(s))).atlasgen))
ifeq ($(filter clean,$(MAKECMDGOALS)),)
$(shell $(call write_if_changed,$(SCENE_STEMS),$(BUILD)/scenes.list))
endif
$(BUILD)/scenes.list:
	@mkdir -p $(@D) && echo "$(SCENE_STEMS)" > $@
# $(call prune_sets,FOLDER,OUTPUTS,STORES)
prune_sets = gone=""; for f in $(1)/* $(1)/.[!.]*; do [ -L "$$f" ] || continue; \
	case "$$(readlink "$$f")" in .*.atlasgen/*) ;; *) continue;; esac; n=$$(basename "$$f"); \
	case " $(2) " in *" $$n "*) ;; *) gone="$$gone $$n"; rm -f "$$f";; esac; done; \
	[ -z "$$gone" ] || echo "removing from $(1):$$gone (no such scene in scenes/)"; \
	for s in $(1)/.*.atlasgen; do [ -d "$$s" ] || continue; \
	case " $(3) " in *" $$(basename "$$s") "*) ;; *) rm -rf "$$s";; esac; done
$(BUILD)/scenes/.pruned: $(BUILD)/scenes.list $(SCENE_SETS) $(SCENE_IMAGES) $(SCENE_EXRS)
	@mkdir -p $(@D) && $(call prune_sets,$(@D),$(SCENE_OUTPUTS),$(SCENE_STORES)) && touch $@
render: $(SCENE_SETS) $(SCENE_IMAGES) $(SCENE_EXRS) $(BUILD)/scenes/.pruned
$(BUILD)/scenes/%.exr $(BUILD)/scenes/%.png &: scenes/%.toml $(HASH_DIR)/scenes/%.toml.sha256 $(BUILD)/scenes/%.dds $(BUILD)/scenes/%.json $(BUILD)/scenes/%.wgsl $(RENDER_CODE) $(RENDER_COMMAND) | $(VENV)/.stamp
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	$(ATLASGEN) render $< --atlas $(BUILD)/scenes/$*.dds -o $(BUILD)/scenes/$*.exr --depfile $(BUILD)/scenes/$*.png.d

# ---- budgets: what the validation and report jobs are run with --------------------------------
# `make validate` and `make report` converge: each stochastic reference gets the samples its noise
# floor needs, and the library page charts cost against error versus physics. `make demo` is a
# quicker first look (README, "Timings"): it passes DEMO_* below, so stochastic references render 16 spp per seed (any figure short
# of its noise floor is labelled with its spp and floor, and warned about), the library page skips
# the physical Pareto charts and says so, and the separable study times each candidate once. The
# options are written to build/budget.args while the Makefile is read by a make asked to validate
# or report, and every such job depends on it: switching between the two budgets redoes the jobs.
VALIDATE_ARGS ?=
REPORT_ARGS ?=
STUDY_ARGS ?=
DEMO_VALIDATE_ARGS := --physical-spp 16 --max-physical-spp 16
DEMO_REPORT_ARGS := --no-physical
DEMO_STUDY_ARGS := --repeats 1
BUDGET := validate $(VALIDATE_ARGS); report library $(REPORT_ARGS); report separable $(STUDY_ARGS)
ifneq ($(filter validate report,$(MAKECMDGOALS)),)
$(shell $(call write_if_changed,$(BUDGET),$(BUILD)/budget.args))
endif
$(BUILD)/budget.args:
	@mkdir -p $(@D) && echo "$(BUDGET)" > $@

validate: $(VALIDATION)/report.json
# STRICT=1 (for CI): fail with exit code 6 when a validation goal is missed (docs/cli.md). The
# check is this phony target's recipe, so every run checks again, not only the one that merged.
ifneq ($(STRICT),)
	$(ATLASGEN) validate --merge $(patsubst %/report.json,%,$(VALIDATED) $(MTLX_VALIDATED)) -o $(VALIDATION) -q --strict
endif

# $(call prune,FOLDER,STEMS,EXT): remove FOLDER's per-material subfolders whose material file (materials/STEM.EXT) is gone.
# Run by the merges, which wait for every per-material job, so nothing is writing there.
prune = for d in $(1)/*/; do [ -d "$$d" ] || continue; n=$$(basename "$$d"); \
	case " $(2) " in *" $$n "*) ;; *) echo "removing $$d (no materials/$$n.$(3))"; rm -rf "$$d";; esac; done

# One material's validation, into its own folder. Its bake result (the cache entry, rewritten or
# touched whenever make re-bakes the material) stands for the material's slices; the atlas is
# order-only: it must be current before validating, but another material's change to it does not
# make this material's report stale.
$(VALIDATED): $(VALIDATION)/materials/%/report.json: materials/%.toml $(CACHE_DIR)/%.npz $(SLICE_CODE) $(VALIDATE_CODE) $(BUILD)/budget.args | $(LIBRARY_ATLAS) $(VENV)/.stamp
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	$(ATLASGEN) validate $< --atlas $(BUILD)/atlas.dds -o $(@D) -q $(VALIDATE_ARGS)

# A MaterialX document's materials: one validation job, into the document's folder.
$(MTLX_VALIDATED): $(VALIDATION)/documents/%/report.json: materials/%.mtlx $(CACHE_DIR)/%.mtlx.stamp $(SLICE_CODE) $(VALIDATE_CODE) $(BUILD)/budget.args | $(LIBRARY_ATLAS) $(VENV)/.stamp
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	$(ATLASGEN) validate $< --atlas $(BUILD)/atlas.dds -o $(@D) -q $(VALIDATE_ARGS)

# The combined page (index.html, report.json, speed_error.png) from the per-material report.json
# files; materials.list re-merges when a material is removed.
$(VALIDATION)/report.json: $(VALIDATED) $(MTLX_VALIDATED) $(BUILD)/materials.list $(VALIDATE_CODE) | $(VENV)/.stamp
	@$(call prune,$(VALIDATION)/materials,$(STEMS),toml)
	@$(call prune,$(VALIDATION)/documents,$(MTLX_STEMS),mtlx)
	$(ATLASGEN) validate --merge $(patsubst %/report.json,%,$(VALIDATED) $(MTLX_VALIDATED)) -o $(VALIDATION) -q

# The separable study measures each material for ~10 s: one job per separable material, then a merge.
$(SEPARABLE_STUDIES): $(SEPARABLE_REPORT)/materials/%/report.json: materials/%.toml $(CACHE_DIR)/%.npz $(SLICE_CODE) $(REPORT_CODE) $(BUILD)/budget.args | $(LIBRARY_ATLAS) $(VENV)/.stamp
	$(ATLASGEN) report separable $< --atlas $(BUILD)/atlas.dds -o $(@D) $(STUDY_ARGS)

# build/separable.list: the separable materials, rewritten only when they change (a material made lambert leaves them
# while materials.list and the remaining studies stay as they were, and its study stayed in the merged report).
ifeq ($(filter clean,$(MAKECMDGOALS)),)
$(shell $(call write_if_changed,$(SEPARABLE_STEMS),$(BUILD)/separable.list))
endif
$(BUILD)/separable.list:
	@mkdir -p $(@D) && echo "$(SEPARABLE_STEMS)" > $@
$(SEPARABLE_REPORT)/index.md: $(SEPARABLE_STUDIES) $(BUILD)/materials.list $(BUILD)/separable.list $(REPORT_CODE) | $(VENV)/.stamp
	@$(call prune,$(SEPARABLE_REPORT)/materials,$(SEPARABLE_STEMS),toml)
	$(ATLASGEN) report separable --merge $(patsubst %/report.json,%,$(SEPARABLE_STUDIES)) -o $(SEPARABLE_REPORT)

# The library page assembles per-material figures that are already measured (manifest, timings,
# the merged validation report): one cheap job over the whole library.
report: $(BUILD)/report/index.html
# A library without separable materials has no separable report to merge or link.
SEPARABLE_INDEX := $(if $(SEPARABLE_STEMS),$(SEPARABLE_REPORT)/index.md)
$(BUILD)/report/index.html: $(BUILD)/atlas.dds $(SEPARABLE_INDEX) $(VALIDATION)/report.json $(REPORT_CODE) $(BUILD)/budget.args | $(VENV)/.stamp
	$(if $(SEPARABLE_STEMS),,rm -rf $(SEPARABLE_REPORT))
	$(ATLASGEN) report library --atlas $(BUILD)/atlas.dds --validation $(VALIDATION) $(if $(SEPARABLE_STEMS),--separable $(SEPARABLE_REPORT)) -o $(BUILD)/report $(REPORT_ARGS)

# One make over the whole graph, in parallel: validation and the separable study are one process
# per material, and no two jobs write the same file. -Otarget keeps each job's output together.
# Parallel jobs share the CPU, and so the reports' timing columns (docs/validation.md); the error
# figures do not depend on it. DEMO_JOBS=1 for quiet-machine timings.
DEMO_JOBS ?= $(shell nproc 2>/dev/null || echo 2)
demo: setup
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	$(MAKE) -j$(DEMO_JOBS) -Otarget atlas render validate report \
	  VALIDATE_ARGS='$(DEMO_VALIDATE_ARGS)' REPORT_ARGS='$(DEMO_REPORT_ARGS)' STUDY_ARGS='$(DEMO_STUDY_ARGS)'
	@echo "demo: build/atlas.dds, build/atlas-preview.png, build/scenes/*.png, build/validation/index.html, build/report/index.html"

# PYTEST_ARGS selects a part of the suite (.ci/run runs the fast subset, then the rest).
PYTEST_ARGS ?=
# Bytecode on, whatever the environment says: pytest caches its rewritten test modules as .pyc,
# so every run after the first skips most of the collection's cost (README, "Development").
test: setup
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -q $(PYTEST_ARGS)

# ruff (lint and format) over the code, mypy over the typed packages (pyproject.toml [tool.mypy]).
lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy

# The fuzz suite (tests/fuzz) with its deep, random "fuzz" profile; `make test` runs its
# quick, fixed "ci" profile. Failing examples are kept in .hypothesis/ and replayed first.
fuzz: setup
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	ATLASGEN_FUZZ_PROFILE=fuzz $(PY) -m pytest -q tests/fuzz --hypothesis-show-statistics

bench: setup
	@mkdir -p "$$XDG_RUNTIME_DIR" && chmod 700 "$$XDG_RUNTIME_DIR"
	$(PY) bench/run.py

# The developer's loop (fast subset, whole suite, demo after make clean), a quarter of an hour:
# its figures go to BENCHMARKS.md and the README's "Timings" table (bench/workflow.py).
bench-workflow: setup
	$(PY) bench/run.py workflow

# What a lent GPU machine needs to run the render benchmark there in one call (bench/device_run.sh):
# the wheels, the Vulkan loader and the atlas, packed into .device/ (README, "Benchmarks on a lent GPU").
device-prepare: $(BUILD)/atlas.dds
	PY=$(PY) bash bench/device_prepare.sh

clean:
	rm -rf $(BUILD) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +

# atlasgen commits each output set whole (docs/cli.md, "Outputs"): a run interrupted just after its
# commit exits 130 with the new set in place. make's default for an interrupted recipe, deleting its
# target, then removed build/atlas.dds and left the rest of the new set without it.
.PRECIOUS: $(CACHE_DIR)/%.npz $(ATLAS_SET) $(SCENE_SETS) $(SCENE_IMAGES) $(SCENE_EXRS) $(VALIDATED) $(MTLX_VALIDATED) \
	$(VALIDATION)/report.json $(SEPARABLE_STUDIES) $(SEPARABLE_REPORT)/index.md $(BUILD)/report/index.html

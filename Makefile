# emogesture — two commands for a fresh machine:
#   make demo   set everything up, then animate the shipped speech clips with the bundled model
#   make test   set everything up, then run the test suite
# and, for maintainers, `make model` rebuilds the bundled model from scratch (about 110 min on 2 cores).
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
EG := $(VENV)/bin/emogesture
# ffmpeg renders the videos; the speech engines build the synthetic corpus; blender checks the BVH and glTF
# exports (its glTF importer needs python3-numpy); pocketsphinx-testdata and asterisk-core-sounds-en-g722 hold real
# recorded speech for the real-speech checks, asterisk-core-sounds-{fr,it,ru}-g722 and asterisk-prompt-{es-co,fr-armelle,it-menardi-wav} and klettres-data real voices a perception can be calibrated with (`calibrate speech --real-voices`), ktuberling-data real voices to validate on (experiments/word_readers.py); Khronos' glTF-Validator and three.js (npm, into build/node) check the glb files; chromium and its
# driver run the web page's browser test
DEMO_APT := ffmpeg
TEST_APT := espeak-ng flite festival festvox-us-slt-hts festvox-kallpc16k festvox-kdlpc16k ffmpeg blender python3-numpy \
	pocketsphinx-testdata asterisk-core-sounds-en-g722 asterisk-core-sounds-fr-g722 asterisk-core-sounds-it-g722 \
	asterisk-core-sounds-ru-g722 asterisk-prompt-es-co asterisk-prompt-fr-armelle asterisk-prompt-it-menardi-wav \
	klettres-data ktuberling-data chromium chromium-driver
GLTF_VALIDATOR := build/node/node_modules/three/package.json
DEMO_DIR ?= outputs/demo
CLIPS := src/emogesture/assets/demo
DEMO_FILES := $(DEMO_DIR)/talk_seed0_0.mp4 $(DEMO_DIR)/talk_emotion-happiness_seed0_0.mp4 \
	$(DEMO_DIR)/talk_emotion-angry_seed0_0.mp4 $(DEMO_DIR)/talk_style-angry_seed0_0.mp4

.PHONY: demo test test-fast model bench setup venv lint clean apt-demo apt-test

demo: apt-demo $(VENV)/.installed $(DEMO_FILES)
	@echo; echo "demo animations (npz for the SMPL-X add-on, bvh for Blender/Unity/Maya, mp4 to watch):"
	@ls -1 $(DEMO_DIR)/talk*_seed0_0.* | sed 's/^/  /'

# one generate command per demo animation; an existing one is kept (delete it to make it again)
$(DEMO_DIR)/talk_seed0_0.mp4:
	$(EG) generate $(CLIPS)/talk.flac -o $(DEMO_DIR)
$(DEMO_DIR)/talk_emotion-happiness_seed0_0.mp4:
	$(EG) generate $(CLIPS)/talk.flac -o $(DEMO_DIR) --emotion happiness
$(DEMO_DIR)/talk_emotion-angry_seed0_0.mp4:
	$(EG) generate $(CLIPS)/talk.flac -o $(DEMO_DIR) --emotion-from $(CLIPS)/angry.flac
$(DEMO_DIR)/talk_style-angry_seed0_0.mp4:
	$(EG) generate $(CLIPS)/talk.flac -o $(DEMO_DIR) --style-from $(CLIPS)/angry.flac

test: apt-test $(VENV)/.installed $(GLTF_VALIDATOR)
	$(PY) -m pytest -q tests

# the quick loop while developing: no apt installs, and no training, browser, Blender, benchmark or Debian-data
# tests (tests/conftest.py marks them)
test-fast: $(VENV)/.installed
	$(PY) -m pytest -q -m "not training and not browser and not blender and not bench and not apt" tests

model: apt-test $(VENV)/.installed
	bash experiments/bundled_model.sh

# speed and memory against this machine's floor (bench/README.md); writes bench/results/cpu.{json,md}
bench: apt-test $(VENV)/.installed
	$(PY) bench/all.py $(BENCH_ARGS)

setup: apt-test $(VENV)/.installed

# Debian packages, installed only when one is missing.
define apt_install
	@missing=""; \
	for p in $(1); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing apt packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing >/dev/null; \
	fi
endef
apt-demo:
	$(call apt_install,$(DEMO_APT))
apt-test:
	$(call apt_install,$(TEST_APT))

# node and npm from Debian where the machine has none (a machine with its own node keeps it)
$(GLTF_VALIDATOR):
	@command -v npm >/dev/null || { SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq nodejs npm >/dev/null; }
	npm install --prefix build/node --no-audit --no-fund --silent gltf-validator@2.0.0-dev.3.10 three@0.170.0

# The CPU build of torch first (pinned), so the package's torch range adds nothing.
$(VENV)/.installed: pyproject.toml Makefile  # a changed install recipe installs again
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[train,test,app]'
	touch $@

lint: setup
	$(VENV)/bin/lint-imports

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache

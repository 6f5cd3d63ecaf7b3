# emogesture — two commands for a fresh machine:
#   make demo   set everything up, then run the main job on the built-in default
#   make test   set everything up, then run the test suite
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
APT_PACKAGES := espeak-ng flite festival festvox-us-slt-hts ffmpeg
DEMO_DIR ?= outputs/demo

.PHONY: demo test setup apt venv lint clean

demo: setup
	$(VENV)/bin/emogesture corpus --out $(DEMO_DIR)/corpus --resume
	$(VENV)/bin/emogesture prepare $(DEMO_DIR)/corpus --out $(DEMO_DIR)/cache

test: setup
	$(PY) -m pytest -q tests

setup: apt $(VENV)/.installed

# System speech engines and ffmpeg; installed only when one is missing.
apt:
	@missing=""; \
	for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing apt packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing >/dev/null; \
	fi

# The CPU build of torch first (pinned), so the package's torch range adds nothing.
$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[train,test]'
	touch $@

lint: setup
	$(VENV)/bin/lint-imports

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache

# smokyslam developer entry points. `make demo` and `make test` set everything up on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
DEMO_DIR ?= demo_output
TORCH_VERSION := 2.13.0
# pytest-xdist workers for `make test`; each test file runs whole in one worker, so its
# module-scoped fixtures are built once.
TEST_WORKERS ?= 2

.PHONY: install demo test lint format bench clean system-deps

install: $(STAMP)

# open3d's wheel links against libusb-1.0; install it when it is missing (Debian/Ubuntu, as root).
system-deps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
		echo "installing libusb-1.0-0 (needed by open3d)"; \
		if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
			(apt-get install -y -q libusb-1.0-0 >/dev/null 2>&1 || \
			 (apt-get update -q >/dev/null && apt-get install -y -q libusb-1.0-0 >/dev/null)) \
			|| echo "warning: could not install libusb-1.0-0; open3d-based features will be unavailable"; \
		else \
			echo "warning: libusb-1.0 missing; install it (e.g. apt-get install libusb-1.0-0) for open3d"; \
		fi; \
	fi

$(STAMP): pyproject.toml setup.py | system-deps
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# torch first: the CPU build of this exact version is what these machines carry.
	$(PY) -m pip install -q torch==$(TORCH_VERSION)
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

demo: install
	$(VENV)/bin/smokyslam demo --out $(DEMO_DIR) --overwrite

test: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: install
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

bench: install
	$(VENV)/bin/smokyslam bench --out bench.json

clean:
	rm -rf $(VENV) $(DEMO_DIR) build *.egg-info .pytest_cache .ruff_cache

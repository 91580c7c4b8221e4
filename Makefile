# ExoStudy's two commands:
#   make run    install everything, migrate the database, start the server on http://127.0.0.1:8000
#   make test   install everything (plus Debian's chromium), run the whole test suite
# Both are idempotent: a second run only re-installs what changed.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
NODE_STAMP := frontend/node_modules/.package-lock.json
# The guide (docs/ as a MkDocs site), served by the app at /guide.
GUIDE_STAMP := site/index.html
export NO_MKDOCS_2_WARNING := 1
# Python writes its compiled bytecode (__pycache__) even where the environment says not to
# (PYTHONDONTWRITEBYTECODE, set on some CI and container images): uv installs no .pyc
# files, so without this every process (each test process, server, worker, device and
# CLI run) compiled NumPy, SciPy, FastAPI, SQLAlchemy and numba from source again, about
# 5 s of CPU each (`import backend.main`: 8.2 s without .pyc files, 3.4 s with them).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test static-checks test-js install lint bench clean-db system-npm system-chromium system-postgresql system-gcc FORCE firmware-check system-firmware fuzz docs-images

run: install $(GUIDE_STAMP)
	$(BIN)/exostudy db upgrade
	$(BIN)/exostudy serve

# pytest runs on two processes more than the machine has cores (many tests wait on
# servers, devices and Chromium in real time: with one process per core a core sat idle
# a third of the time, with one more about an eighth; docs/tests.md), a test module per
# process at a time (`--dist
# loadfile`: a module's shared fixtures are built once); the static checks and
# firmware-check run beside it, their output printed after pytest's. Fails if either
# part failed. The static checks run at a lower priority (nice 10): they fill the time
# pytest's processes spend waiting on servers and devices instead of slowing them (on a
# fresh clone, at equal priority, they stretched the numba warm-up from about 40 s to
# 110 s). Before pytest, beside the static checks, one process compiles the numba
# kernels into their cache (tests/warm_kernels.py), so that pytest's processes and the
# servers they start load them instead of each compiling them at once. docs/tests.md.
TEST_PROCESSES ?= $(shell echo $$(( $$(nproc) + 2 )))
test: install system-chromium system-postgresql system-firmware
	@log=$$(mktemp); out=$$(mktemp); rc=$$(mktemp); \
	nice -n 10 $(MAKE) --no-print-directory static-checks >"$$log" 2>&1 & checks=$$!; \
	$(BIN)/python -m tests.warm_kernels || echo "warming the numba kernels failed: pytest compiles them"; \
	{ $(BIN)/python -m pytest -n $(TEST_PROCESSES) --dist loadfile; echo $$? >"$$rc"; } | tee "$$out"; \
	tests=$$(cat "$$rc"); \
	wait $$checks; checked=$$?; \
	echo "== ruff, mypy, mkdocs, firmware-check (ran beside pytest) =="; \
	cat "$$log"; \
	awk '/slowest test files \(seconds/ {on=1; print; next} on && /^ / {print; next} {on=0}' "$$out"; \
	echo "== pytest exit status $$tests, static checks exit status $$checked; pytest said: =="; \
	tail -n 1 "$$out"; rm -f "$$log" "$$out" "$$rc"; \
	[ $$tests -eq 0 ] && [ $$checked -eq 0 ]

static-checks: firmware-check
	$(BIN)/ruff check controller backend tests bench migrations tools/docs setup.py
	$(BIN)/mypy
	$(BIN)/mkdocs build --strict --quiet

# The C device firmware core on Linux against the simulated wearer (gcc, warnings as
# errors); its own Makefile decides what is out of date. docs/device-firmware.md.
C_DEVICE := firmware/build/exostudy-device

install: $(VENV)/.installed $(NODE_STAMP) $(C_DEVICE)

$(C_DEVICE): FORCE | system-gcc
	$(MAKE) -s -C firmware/ports/linux-sim

FORCE:

system-gcc:
	@command -v gcc >/dev/null 2>&1 || { $(SUDO) apt-get update && $(SUDO) apt-get install -y gcc; }

# Firmware for real boards (docs/hardware-bringup-lab.md): the portable core's own tests
# (plain and under the address and undefined-behaviour sanitizers), the core and the
# Nucleo-F767ZI port cross-compiled for the Cortex-M7 (ELF linked, size printed), the
# Linux single-board-computer port with the host gcc, and both ports' own tests under
# the sanitizers (each prints "N passed, 0 failed"). The emulated mps2-an500 port is
# built and booted in QEMU by pytest (tests/firmware/test_qemu_device.py; not here, so
# that two makes never write its objects at once); system-firmware also installs
# qemu-system-arm, and `test` depends on it so that pytest finds the tools.
# Last, the libFuzzer harnesses' bounded run (firmware/fuzz: 15 s each, fixed seed, must
# find nothing; docs/device-firmware.md, "Fuzzing"); `make fuzz` runs them 10 minutes each.
firmware-check: system-firmware system-gcc
	$(MAKE) -C firmware test
	$(MAKE) -C firmware/ports/nucleo-f767zi check
	$(MAKE) -C firmware/ports/linux-sbc check
	$(MAKE) -C firmware/fuzz check

system-firmware:
	@command -v arm-none-eabi-gcc >/dev/null 2>&1 || { $(SUDO) apt-get update && $(SUDO) apt-get install -y gcc-arm-none-eabi libnewlib-arm-none-eabi; }
	@command -v qemu-system-arm >/dev/null 2>&1 || { $(SUDO) apt-get update && $(SUDO) apt-get install -y qemu-system-arm; }
	@test -f /usr/include/gpiod.h || { $(SUDO) apt-get update && $(SUDO) apt-get install -y libgpiod-dev; }
	@command -v clang >/dev/null 2>&1 || { $(SUDO) apt-get update && $(SUDO) apt-get install -y clang; }
	@ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-*.a >/dev/null 2>&1 || \
		{ $(SUDO) apt-get update && $(SUDO) apt-get install -y libclang-rt-14-dev; }

# The fuzz harnesses' long run (firmware/fuzz; FUZZ_SECONDS per harness, default 600).
fuzz: system-firmware
	$(MAKE) -C firmware/fuzz fuzz

$(BIN)/python:
	$(PYTHON) -m venv $(VENV) || { echo "python venv failed: on Debian, apt-get install python3-venv"; exit 1; }

# uv (from PyPI, into the venv) installs the same packages as pip in a fraction of the
# time (7 s instead of about 55 s for a new venv here); if uv cannot be had or fails (an
# index only pip is configured for, say), pip installs them instead.
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	@# Python 3.11's own pip installs this project (editable, pyproject): upgrade only an older one.
	$(BIN)/python -c 'import pip, sys; sys.exit(int(pip.__version__.split(".")[0]) < 22)' || \
		$(BIN)/python -m pip install --quiet --upgrade pip
	{ $(BIN)/python -m pip install --quiet uv && \
		$(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[dev,postgres]'; } || \
		$(BIN)/python -m pip install --quiet -e '.[dev,postgres]'
	touch $@

$(NODE_STAMP): frontend/package.json frontend/package-lock.json | system-npm
	cd frontend && npm ci --no-audit --no-fund
	touch $@

$(GUIDE_STAMP): mkdocs.yml tools/docs/hooks.py $(shell find docs bench/results -type f 2>/dev/null) | $(VENV)/.installed
	$(BIN)/mkdocs build --strict --quiet

# Debian packages the project needs and a fresh machine may lack.
system-npm:
	@command -v npm >/dev/null 2>&1 || { $(SUDO) apt-get update && $(SUDO) apt-get install -y npm; }

# The database-facing tests also run on a throwaway PostgreSQL cluster (tests/databases.py
# runs initdb and pg_ctl in a temporary folder; no system service is needed).
system-postgresql:
	@command -v pg_ctl >/dev/null 2>&1 || ls /usr/lib/postgresql/*/bin/pg_ctl >/dev/null 2>&1 || \
		{ $(SUDO) apt-get update && $(SUDO) apt-get install -y postgresql; }

# Debian's chromium, and its headless shell (the same engine without the browser's
# windows, built from the same Debian source; what Playwright itself runs for headless
# tests), which the browser tests use: a page costs it about 40 % less CPU. Without the
# shell (it could not be installed) they run in chromium, more slowly.
system-chromium:
	@{ command -v chromium && command -v chromium-headless-shell; } >/dev/null 2>&1 || \
		{ $(SUDO) apt-get update && $(SUDO) apt-get install -y chromium chromium-headless-shell; } || \
		{ command -v chromium >/dev/null 2>&1 && \
		  echo "chromium-headless-shell could not be installed: the browser tests use chromium"; }

lint: install
	$(BIN)/ruff check controller backend tests bench migrations tools/docs setup.py
	$(BIN)/mypy
	frontend/node_modules/.bin/eslint --max-warnings 0 -c frontend/eslint.config.mjs frontend tests/frontend

# The console's JavaScript alone: its `node --test` unit tests and ESLint (pytest runs
# both in `make test` too: tests/frontend/test_javascript.py).
test-js: install
	$(BIN)/python -m pytest tests/frontend -q

bench: install
	$(BIN)/python bench/run_all.py

# The docs' screenshots that browser tests take (docs/img/): the test asserts on the
# page, then saves its picture when EXOSTUDY_DOCS_IMAGES is set.
docs-images: install system-chromium
	EXOSTUDY_DOCS_IMAGES=1 $(BIN)/python -m pytest tests/browser/test_wearer_page.py -q -p no:randomly -n 0

clean-db:
	rm -f var/exostudy.db var/exostudy.db-wal var/exostudy.db-shm

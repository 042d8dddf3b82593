# scicap — one build for everything (GNU make).
# Targets: all deps demo check check-asan check-gv check-vm check-web bench fuzz install clean.  `make help` lists them.

PREFIX  ?= /usr/local
DESTDIR ?=
BUILD   ?= build
SCICAP_DATA ?= $(abspath ../shared/data)
export SCICAP_DATA

CC      ?= gcc
CXX     ?= g++
ifeq ($(origin CC),default)
CC := gcc
endif
OPT     ?= -O3
# No -ffast-math anywhere: it breaks the NaN/Inf checks the numerics rely on (docs/architecture.md, Numerics).
CFLAGS  ?= $(OPT) -g
CXXFLAGS ?= $(OPT) -g
WARN    := -Wall -Wextra -Werror -Wshadow -Wno-unused-parameter -Wno-format-truncation
PKGS    := OpenImageIO matio zlib jansson openblas hidapi-hidraw libusb-1.0 libgpiod libsystemd aravis-0.8 libmicrohttpd
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   := $(shell pkg-config --libs $(PKGS) 2>/dev/null)
# libgpiod 1.6 (Debian 12) and 2.x have different APIs; drivers/ picks one at compile time.
GPIOD_MAJOR := $(shell pkg-config --modversion libgpiod 2>/dev/null | cut -d. -f1)
# SANITIZE=1 (make check-asan): AddressSanitizer and UndefinedBehaviorSanitizer in every object and program; any
# report fails the test that triggered it (UBSan does not recover).
# GCC's object-size warnings misfire under ASan (a strstr after a checked strstr in tests/integration/test_cli_help.c):
# they stay warnings there, every other warning is still an error.
comma := ,
SAN_FLAGS := $(if $(SANITIZE),-fsanitize=address$(comma)undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer \
               -Wno-error=stringop-overread)
ALL_CFLAGS   = -std=c11 -D_GNU_SOURCE -fopenmp $(WARN) -I. $(PKG_CFLAGS) -DSCICAP_GPIOD_MAJOR=$(or $(GPIOD_MAJOR),0) \
               -DSCICAP_VERSION='"$(VERSION)"' -DSCICAP_DATADIR='"$(PREFIX)/share/scicap"' $(CFLAGS) $(SAN_FLAGS) $(CPPFLAGS)
ALL_CXXFLAGS = -std=c++17 -fopenmp $(filter-out -Wshadow,$(WARN)) -I. $(PKG_CFLAGS) $(CXXFLAGS) $(SAN_FLAGS) $(CPPFLAGS)
LDLIBS_ALL   = $(PKG_LIBS) -lgif -lstdc++ -lm -lpthread $(LDLIBS)
VERSION := $(shell git describe --always --dirty 2>/dev/null || echo 0.1)

# Every .c under these folders goes into libscicap.a: adding a module needs no Makefile edit.
LIB_DIRS := base io recon recon/cnn recon/nerf sim drivers daemon
LIB_C    := $(filter-out daemon/main.c,$(foreach d,$(LIB_DIRS),$(wildcard $(d)/*.c)))
LIB_CXX  := $(foreach d,$(LIB_DIRS),$(wildcard $(d)/*.cpp))
LIB_OBJ  := $(LIB_C:%.c=$(BUILD)/%.o) $(LIB_CXX:%.cpp=$(BUILD)/%.o)
LIB      := $(BUILD)/libscicap.a

CLI_OBJ  := $(patsubst %.c,$(BUILD)/%.o,$(wildcard cli/*.c))
# The command line but its main() (cli/main.c holds main and the command table only): the tests link it, so they
# call its functions (cli/recon_opts.h) as scicap does. Every other cli/*.c is in it: no edit for a new one.
CLI_LIB  := $(BUILD)/libscicap-cli.a
BINS     := $(BUILD)/scicap $(if $(wildcard daemon/main.c),$(BUILD)/scicapd)

TEST_SRC := $(wildcard tests/unit/test_*.c tests/stability/test_*.c tests/integration/test_*.c)
TEST_BIN := $(TEST_SRC:%.c=$(BUILD)/%)
TEST_HELPERS := $(patsubst %.c,$(BUILD)/%.o,$(wildcard tests/helpers/*.c))
# built through a pattern rule, they would count as intermediate and be deleted after the run that made them
.SECONDARY: $(TEST_HELPERS)
BENCH_SRC := $(wildcard bench/bench_*.c)
BENCH_BIN := $(BENCH_SRC:%.c=$(BUILD)/%)

# Debian 12 packages the project needs, and what each is for (README, "Dependencies").
DEB_PKGS := build-essential pkg-config g++ libopenimageio-dev openimageio-tools libmatio-dev libjansson-dev \
            libcmocka-dev libopenblas-dev libhidapi-dev libusb-1.0-0-dev libgpiod-dev gpiod libsystemd-dev \
            gnuplot-nox clang libclang-rt-14-dev libaravis-dev aravis-tools systemd zlib1g-dev \
            python3-dev python3-numpy python3-pytest slurm-wlm munge libgif-dev \
            libmicrohttpd-dev libjs-chart.js chromium
# Only for `make bench`: the PyTorch side of bench_pnp_ffdnet's speed comparison (not needed to build or test).
BENCH_PKGS := python3-torch

.PHONY: all deps deps-bench demo check check-asan check-gv check-vm bench bench-report fuzz install clean help tests benches
.PHONY: python check-python check-slurm check-web
all: $(BINS)

help:
	@echo "make deps      install missing Debian packages (apt-get)"
	@echo "make deps-bench  also what make bench uses beyond the build (PyTorch, for one speed comparison)"
	@echo "make demo      build and run the main job on its embedded default"
	@echo "make check     build and run every test (C tests, then the Python module's pytest tests)"
	@echo "make python    the Python module in BUILD/python (PYTHONPATH=BUILD/python python3 -c 'import scicap')"
	@echo "make check-asan  every test again under ASan + UBSan at -O2 (build-asan/)"
	@echo "make check-slurm  scicap batch --slurm on a single-node Slurm started in a temporary folder"
	@echo "make check-gv  the GenICam (Aravis) backend against a fake GigE Vision camera on loopback"
	@echo "make check-vm  run the device tests against real kernel drivers under qemu"
	@echo "make check-web  the web view: its security tests, then the page in headless Chromium (screenshots kept)"
	@echo "make bench     run the benchmarks and print the figures (writes bench/results/)"
	@echo "make bench-report  accuracy against time for every method (bench/results.csv, report, plots)"
	@echo "make install   install binaries, units, config, man pages (PREFIX, DESTDIR)"

# The builds inside check, demo and the other test targets use every core unless the caller chose (make -jN passes
# its own job server down; JOBS= builds serially).
JOBS ?= $(if $(filter -j%,$(MAKEFLAGS)),,-j$(shell nproc))

# $(1): the packages; installs those not installed, with sudo unless root.
define apt_install
	@missing=$$(for p in $(1); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "deps: installing$$(echo $$missing | sed 's/^/ /')"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	else echo "deps: all $(words $(1)) Debian packages present"; fi
endef

deps:
	$(call apt_install,$(DEB_PKGS))

deps-bench: deps
	$(call apt_install,$(BENCH_PKGS))

$(LIB): $(LIB_OBJ)
	@rm -f $@
	ar rcs $@ $^

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(PIC_EXTRA) -MMD -MP -c $< -o $@

$(BUILD)/%.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(ALL_CXXFLAGS) $(PIC_EXTRA) -MMD -MP -c $< -o $@

$(CLI_LIB): $(filter-out $(BUILD)/cli/main.o,$(CLI_OBJ))
	@rm -f $@
	ar rcs $@ $^

$(BUILD)/scicap: $(CLI_OBJ) $(LIB)
	$(CC) $(ALL_CFLAGS) -o $@ $(CLI_OBJ) $(LIB) $(LDLIBS_ALL)

$(BUILD)/scicapd: $(BUILD)/daemon/main.o $(LIB)
	$(CC) $(ALL_CFLAGS) -o $@ $< $(LIB) $(LDLIBS_ALL)

$(BUILD)/tests/%: tests/%.c $(TEST_HELPERS) $(CLI_LIB) $(LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -MMD -MP -o $@ $< $(TEST_HELPERS) $(CLI_LIB) $(LIB) $(LDLIBS_ALL) -lcmocka

$(BUILD)/bench/%: bench/%.c $(LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -MMD -MP -o $@ $< $(LIB) $(LDLIBS_ALL)

tests: $(TEST_BIN) $(BINS)
benches: $(BENCH_BIN) $(BINS)

# The Python module (python/, docs/python.md): the extension scicap._scicap against the numpy C API, linked with an
# archive of the library's offline layers ($(BUILD)/pic/libscicap.a: the same objects the programs link, compiled
# position-independent once; -fno-semantic-interposition keeps the inlining -fPIE allows, so the programs run the
# same code), and the pure-Python package beside it, so that
# PYTHONPATH=$(BUILD)/python python3 -c 'import scicap' works from the build tree. Debian's python3, not a PATH one.
PYTHON   ?= /usr/bin/python3
PY_INFO  := $(shell $(PYTHON) -c 'import sysconfig, numpy; print(sysconfig.get_paths()["include"], \
              numpy.get_include(), sysconfig.get_config_var("EXT_SUFFIX"), sysconfig.get_python_version())' 2>/dev/null)
PY_CFLAGS := $(addprefix -I,$(wordlist 1,2,$(PY_INFO)))
PY_EXT   := $(BUILD)/python/scicap/_scicap$(word 3,$(PY_INFO))
PY_SITE  ?= $(PREFIX)/lib/python$(word 4,$(PY_INFO))/dist-packages
PIC_DIRS := $(filter-out drivers daemon,$(LIB_DIRS))
PIC_OBJ  := $(patsubst %.c,$(BUILD)/%.o,$(foreach d,$(PIC_DIRS),$(wildcard $(d)/*.c))) \
            $(patsubst %.cpp,$(BUILD)/%.o,$(foreach d,$(PIC_DIRS),$(wildcard $(d)/*.cpp)))
PIC_LIB  := $(BUILD)/pic/libscicap.a
PY_OBJ   := $(patsubst %.c,$(BUILD)/pic/%.o,$(wildcard python/*.c))
PY_PURE  := $(patsubst python/%,$(BUILD)/python/%,$(wildcard python/scicap/*.py))

PIC_FLAGS := -fPIC -fno-semantic-interposition
$(PIC_OBJ): PIC_EXTRA = $(PIC_FLAGS)
# make does not see a change of flags: a build folder from before these objects were position-independent (no stamp)
# rebuilds them once, instead of failing to link the extension
PIC_STAMP := $(BUILD)/.pic-objects
$(PIC_STAMP):
	@mkdir -p $(dir $@) && touch $@
$(PIC_OBJ): $(PIC_STAMP)

$(BUILD)/pic/python/%.o: python/%.c
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -fPIC $(PY_CFLAGS) -fvisibility=hidden -MMD -MP -c $< -o $@

$(PIC_LIB): $(PIC_OBJ)
	@mkdir -p $(dir $@) && rm -f $@
	ar rcs $@ $^

# --exclude-libs: the library's symbols stay inside the module (only PyInit__scicap is exported).
$(PY_EXT): $(PY_OBJ) $(PIC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -shared -Wl,--exclude-libs,ALL -o $@ $(PY_OBJ) $(PIC_LIB) $(LDLIBS_ALL)

$(BUILD)/python/scicap/%.py: python/scicap/%.py
	@mkdir -p $(dir $@)
	cp $< $@

python: $(PY_EXT) $(PY_PURE)

# A test build with one method more (tests/extra_method/, docs: recon/solver.h): the normal build's objects but
# recon/solver.o, which is compiled again with -DSCICAP_EXTRA_SOLVER naming the extra method's row, plus that
# method's object; scicap, scicapd and the Python module linked against it in $(BUILD)/extra-method/. That one row
# is the only edit a new method makes: tests/integration/test_extra_method.c and tests/python/test_extra_method.py
# look for it in every interface. Costs two compiles and the links.
XM        := $(BUILD)/extra-method
XM_SOLVER := sci_toy_mean_solver
XM_C      := $(wildcard tests/extra_method/*.c)
XM_LIB    := $(XM)/libscicap.a
XM_PIC_LIB := $(XM)/pic/libscicap.a
XM_PY_EXT := $(XM)/python/scicap/_scicap$(word 3,$(PY_INFO))
XM_PY_PURE := $(patsubst python/%,$(XM)/python/%,$(wildcard python/scicap/*.py))
XM_BINS   := $(XM)/scicap $(XM)/scicapd

$(XM)/recon/solver.o: recon/solver.c
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(PIC_FLAGS) -DSCICAP_EXTRA_SOLVER=$(XM_SOLVER) -MMD -MP -c $< -o $@
$(XM_C:%.c=$(BUILD)/%.o): PIC_EXTRA = $(PIC_FLAGS)
$(XM)/recon/solver.o $(XM_C:%.c=$(BUILD)/%.o): $(PIC_STAMP)

$(XM_LIB): $(filter-out $(BUILD)/recon/solver.o,$(LIB_OBJ)) $(XM)/recon/solver.o $(XM_C:%.c=$(BUILD)/%.o)
	@rm -f $@
	ar rcs $@ $^

$(XM_PIC_LIB): $(filter-out $(BUILD)/recon/solver.o,$(PIC_OBJ)) $(XM)/recon/solver.o $(XM_C:%.c=$(BUILD)/%.o)
	@mkdir -p $(dir $@) && rm -f $@
	ar rcs $@ $^

$(XM)/scicap: $(CLI_OBJ) $(XM_LIB)
	$(CC) $(ALL_CFLAGS) -o $@ $(CLI_OBJ) $(XM_LIB) $(LDLIBS_ALL)

$(XM)/scicapd: $(BUILD)/daemon/main.o $(XM_LIB)
	$(CC) $(ALL_CFLAGS) -o $@ $< $(XM_LIB) $(LDLIBS_ALL)

$(XM_PY_EXT): $(PY_OBJ) $(XM_PIC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -shared -Wl,--exclude-libs,ALL -o $@ $(PY_OBJ) $(XM_PIC_LIB) $(LDLIBS_ALL)

$(XM)/python/scicap/%.py: python/scicap/%.py
	@mkdir -p $(dir $@)
	cp $< $@

# The C test runs the extra build's programs; the pytest one its module (check-python); the method table's own
# test (every row's rules, presets, JSON round trip, run and cancel) runs again on the extra build's table.
$(BUILD)/tests/integration/test_extra_method: $(XM_BINS)
XM_TEST_BIN := $(XM)/tests/unit/test_solver
$(XM)/tests/%: tests/%.c $(TEST_HELPERS) $(CLI_LIB) $(XM_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -MMD -MP -o $@ $< $(TEST_HELPERS) $(CLI_LIB) $(XM_LIB) $(LDLIBS_ALL) -lcmocka
tests: $(XM_TEST_BIN)
python-extra-method: $(XM_PY_EXT) $(XM_PY_PURE)
.PHONY: python-extra-method

# The C tests, then the Python module's (tests/python, pytest): both always run; either failing fails the check.
check: deps
	@$(MAKE) --no-print-directory $(JOBS) tests python
	@rc=0; BUILD=$(BUILD) SCICAP_DATA="$(SCICAP_DATA)" tests/run $(TEST_BIN) $(XM_TEST_BIN) tests/vm/test_resolve || rc=1; \
	  $(MAKE) --no-print-directory check-python || rc=1; exit $$rc

check-python: python python-extra-method $(BINS)
	@echo "tests/python (pytest, module from $(BUILD)/python):"
	@BUILD=$(BUILD) SCICAP_DATA="$(SCICAP_DATA)" PYTHONPATH=$(abspath $(BUILD)/python) \
	  $(PYTHON) -m pytest -q -p no:cacheprovider --durations=5 tests/python

# Every test again with ASan + UBSan at -O2, in its own build folder (build-asan), programs the tests start
# (scicap, scicapd) included. Leak checking is off: the goal is memory errors and undefined behaviour. -O2, not -O1:
# the numerical tests run 20-30 % less CPU time (test_gaptv 59 s against 73, test_nerf_scinerf 36 against 51).
ASAN_BUILD ?= build-asan
check-asan: deps
	@$(MAKE) --no-print-directory $(JOBS) BUILD=$(ASAN_BUILD) OPT=-O2 SANITIZE=1 tests
	@ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 BUILD=$(ASAN_BUILD) SCICAP_DATA="$(SCICAP_DATA)" \
	  tests/run $(TEST_BIN:$(BUILD)/%=$(ASAN_BUILD)/%) $(XM_TEST_BIN:$(BUILD)/%=$(ASAN_BUILD)/%)

demo: deps
	@$(MAKE) --no-print-directory $(JOBS) all
	@BUILD=$(BUILD) cli/demo-daemon.sh

# GenICam over GigE Vision on loopback (tests/aravis-gv/): Aravis's arv-fake-gv-camera-0.8 serves a camera on
# 127.0.0.1 and the Aravis backend captures from it; the script starts and stops the camera, bounded in time.
GV_TEST_BIN := $(patsubst %.c,$(BUILD)/%,$(wildcard tests/aravis-gv/test_*.c))
check-gv: deps
	@$(MAKE) --no-print-directory $(JOBS) $(GV_TEST_BIN)
	@BUILD=$(BUILD) tests/aravis-gv/run $(GV_TEST_BIN)

# scicap batch --slurm against a real single-node Slurm started in a temporary folder (tests/slurm/run: munge,
# slurmctld, slurmd; 8 reconstructions as an array job, one task cancelled and resubmitted; under 5 minutes).
check-slurm: deps
	@$(MAKE) --no-print-directory $(JOBS) all
	@BUILD=$(BUILD) tests/slurm/run

# The web view (docs/web.md): tests/integration/test_web_*.c (also part of check), then the page in Debian's
# headless chromium against scicapd on the simulated bench (tests/web/run); its screenshots at phone and desktop
# size stay in $(BUILD)/web-artifacts (WEB_ARTIFACTS) for CI to keep.
WEB_TEST_BIN := $(patsubst %.c,$(BUILD)/%,$(wildcard tests/integration/test_web_*.c))
WEB_ARTIFACTS ?= $(abspath $(BUILD)/web-artifacts)
check-web: deps
	@$(MAKE) --no-print-directory $(JOBS) all $(WEB_TEST_BIN)
	@BUILD=$(BUILD) SCICAP_DATA="$(SCICAP_DATA)" tests/run $(WEB_TEST_BIN)
	@BUILD=$(BUILD) SCICAP_WEB_ARTIFACTS="$(WEB_ARTIFACTS)" tests/web/run

# Kernel-level device tests under qemu (tests/vm/, docs/check-vm.md): the drivers against the real
# V4L2 (vivid), hidraw (uhid) and GPIO (gpio-sim) subsystems. VM_CACHE keeps downloads and builds between runs.
VM_CACHE ?= $(HOME)/.cache/scicap-vm
check-vm: deps
	@$(MAKE) --no-print-directory $(JOBS) all tests
	@BUILD=$(BUILD) VM_CACHE="$(VM_CACHE)" tests/vm/run

bench: deps-bench
	@$(MAKE) --no-print-directory $(JOBS) benches
	@BUILD=$(BUILD) SCICAP_DATA="$(SCICAP_DATA)" bench/run $(BENCH_BIN)

# The published accuracy-against-time report: every method over its cost knobs on the fixed suite; writes
# bench/results.csv, bench/results/report.md and the plots, and copies the report into docs/benchmarks.md.
bench-report: deps
	@$(MAKE) --no-print-directory $(JOBS) all
	$(BUILD)/scicap bench --full --data "$(SCICAP_DATA)"
	@bench/update-docs

install: all python
	install -d $(DESTDIR)$(PREFIX)/bin
	install -m 755 $(BINS) $(DESTDIR)$(PREFIX)/bin/
	install -d $(DESTDIR)$(PY_SITE)/scicap
	install -m 644 $(PY_EXT) $(PY_PURE) $(DESTDIR)$(PY_SITE)/scicap/
	install -d $(DESTDIR)$(PREFIX)/share/scicap/scenes
	install -m 644 bench/results.csv $(DESTDIR)$(PREFIX)/share/scicap/results.csv
	install -d $(DESTDIR)$(PREFIX)/share/scicap/web
	install -m 644 daemon/web/index.html daemon/web/app.js daemon/web/style.css $(DESTDIR)$(PREFIX)/share/scicap/web/
	install -m 644 etc/scenes/*.json etc/scenes/*.pgm $(DESTDIR)$(PREFIX)/share/scicap/scenes/
	install -d $(DESTDIR)$(PREFIX)/share/scicap/scenes/textures
	install -m 644 etc/scenes/textures/*.png etc/scenes/textures/README.md $(DESTDIR)$(PREFIX)/share/scicap/scenes/textures/
	install -d $(DESTDIR)$(PREFIX)/share/scicap/examples
	install -m 644 etc/scicapd-aravis.json etc/scicapd-v4l2.json $(DESTDIR)$(PREFIX)/share/scicap/examples/
	install -d $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 644 docs/man/*.1 $(DESTDIR)$(PREFIX)/share/man/man1/
	install -d $(DESTDIR)/etc/scicap $(DESTDIR)/lib/systemd/system $(DESTDIR)/usr/lib/sysusers.d \
	  $(DESTDIR)/usr/lib/tmpfiles.d $(DESTDIR)/etc/udev/rules.d $(DESTDIR)$(PREFIX)/share/man/man8
	[ -e $(DESTDIR)/etc/scicap/scicapd.json ] || install -m 644 etc/scicapd.json $(DESTDIR)/etc/scicap/scicapd.json
	sed 's|/usr/local/bin|$(PREFIX)/bin|g' systemd/scicapd.service > $(DESTDIR)/lib/systemd/system/scicapd.service
	install -m 644 systemd/scicapd.sysusers $(DESTDIR)/usr/lib/sysusers.d/scicapd.conf
	install -m 644 systemd/scicapd.tmpfiles $(DESTDIR)/usr/lib/tmpfiles.d/scicapd.conf
	install -m 644 systemd/70-scicap.rules $(DESTDIR)/etc/udev/rules.d/70-scicap.rules
	install -m 644 docs/man/scicapd.8 $(DESTDIR)$(PREFIX)/share/man/man8/

# Fuzzers: libFuzzer (clang) over the parsers that take outside input: each tests/fuzz/fuzz_<x>.c is one target,
# linked against the whole library built again with clang, instrumented (coverage, ASan, UBSan) in
# $(BUILD)/fuzz/obj. Seeds, including bad inputs found by earlier runs, are in tests/fuzz/corpus/<x>/; what a run
# finds goes to $(BUILD)/fuzz/corpus-fuzz_<x>. FUZZ_SECONDS per target (default 60).
FUZZ_SECONDS ?= 60
FUZZ_SRC := $(wildcard tests/fuzz/fuzz_*.c)
FUZZ_BIN := $(FUZZ_SRC:tests/fuzz/%.c=$(BUILD)/fuzz/%)
FUZZ_SAN := -g -O1 -fno-omit-frame-pointer -fopenmp -Wno-pass-failed -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZ_CFLAGS := -std=c11 -D_GNU_SOURCE $(FUZZ_SAN) -I. $(PKG_CFLAGS) -DSCICAP_GPIOD_MAJOR=$(or $(GPIOD_MAJOR),0) \
               -DSCICAP_VERSION='"$(VERSION)"' -DSCICAP_DATADIR='"$(PREFIX)/share/scicap"'
FUZZ_OBJ := $(LIB_C:%.c=$(BUILD)/fuzz/obj/%.o) $(LIB_CXX:%.cpp=$(BUILD)/fuzz/obj/%.o)
FUZZ_LIB := $(BUILD)/fuzz/libscicap-fuzz.a
$(BUILD)/fuzz/obj/%.o: %.c
	@mkdir -p $(dir $@)
	clang $(FUZZ_CFLAGS) -fsanitize=fuzzer-no-link -MMD -MP -c $< -o $@
$(BUILD)/fuzz/obj/%.o: %.cpp
	@mkdir -p $(dir $@)
	clang++ -std=c++17 $(FUZZ_SAN) -fno-sanitize=vptr -fsanitize=fuzzer-no-link -I. $(PKG_CFLAGS) -MMD -MP -c $< -o $@
$(FUZZ_LIB): $(FUZZ_OBJ)
	@rm -f $@
	ar rcs $@ $^
$(BUILD)/fuzz/%: tests/fuzz/%.c $(FUZZ_LIB)
	@mkdir -p $(dir $@)
	clang $(FUZZ_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_LIB) $(PKG_LIBS) -lgif -lstdc++ -lm -lpthread
fuzz: deps
	@$(MAKE) --no-print-directory $(JOBS) $(FUZZ_BIN)
	@set -e; for f in $(FUZZ_BIN); do n=$$(basename $$f); mkdir -p $(BUILD)/fuzz/corpus-$$n; \
	  seeds=tests/fuzz/corpus/$${n#fuzz_}; [ -d $$seeds ] || seeds=; \
	  echo "fuzz: $$n for $(FUZZ_SECONDS) s"; \
	  rc=0; $$f -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 -artifact_prefix=$(BUILD)/fuzz/$$n- \
	    $(BUILD)/fuzz/corpus-$$n $$seeds > $(BUILD)/fuzz/$$n.log 2>&1 || rc=$$?; tail -n 12 $(BUILD)/fuzz/$$n.log; \
	  [ $$rc -eq 0 ] || { echo "fuzz: $$n FAILED (log $(BUILD)/fuzz/$$n.log, input $(BUILD)/fuzz/$$n-*)"; exit 1; }; \
	done

clean:
	rm -rf $(BUILD)

-include $(LIB_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(TEST_BIN:=.d) $(BENCH_BIN:=.d) $(GV_TEST_BIN:=.d) $(FUZZ_OBJ:.o=.d)
-include $(PY_OBJ:.o=.d) $(XM)/recon/solver.d $(XM_C:%.c=$(BUILD)/%.d) $(XM_TEST_BIN:=.d)

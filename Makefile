# btf-stream: compress measured BTFs by k-view PCA and stream them to WebGL2.
# Targets: setup all build test e2e check asan bench chart demo install clean
# (doc/cli.md section 13). The rooms and which may use which: doc/architecture.md.

SHELL    := /bin/bash
BUILD    ?= build
SHARED   ?= $(abspath $(CURDIR)/../shared)
export BTF_SHARED := $(SHARED)
export BTF_ROOT := $(CURDIR)

CC       ?= cc
CXX      ?= g++
OPT      ?= -O2 -g
WARN     := -Wall -Wextra -Werror
CFLAGS   += -std=c11 $(WARN) $(OPT) -fopenmp -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L -MMD -MP
CXXFLAGS += -std=c++17 $(WARN) $(OPT) -MMD -MP
SAN      ?=
CFLAGS   += $(SAN)
CXXFLAGS += $(SAN)
LDFLAGS  += $(SAN) -fopenmp

# $(call pkg,--cflags|--libs,NAMES): pkg-config's answer; a missing package stops
# the build with pkg-config's own message. Deferred (=): only recipes expand it,
# so `make setup` can install the packages first.
pkg = $(call pkg__or_stop,$(shell pkg-config $(1) $(2) 2>&1 || echo PKG-CONFIG-FAILED),$(2))
pkg__or_stop = $(if $(filter PKG-CONFIG-FAILED,$(1)),$(error pkg-config $(2): $(filter-out PKG-CONFIG-FAILED,$(1)) (run 'make setup')),$(1))

# --- Rooms: each folder one archive, one include path, dependencies one way ---
# tools/check_rooms.sh $(BUILD) keeps it so (run by `make check` and `make test`):
# no #include of a room a room may not use, no call between object files that goes
# the wrong way or round a circle. Its room table mirrors the INC lines below
# (and server/build.mk's).
# codec/        product library, one archive; inner rooms (doc/architecture.md), each
#               with the include path of the rooms it may use, bottom first:
#   include/    the public headers, the only ones `make install` installs
#   common/     core, direction sets and tables, interpolation, hull, colour, metrics,
#               view streams, view blocks, file helpers
#   image/      image files (OpenImageIO, PNG, WebP)
#   format/     the package format: manifest, residual levels, weight tables
#   input/      readers of measured BTFs; btf_input.c the one dispatcher
#   decompress/ package reader, decoder, level selection
#   compress/   PCA, rate control, budget search, writer, level builder, thumbnail
#   image/btf_image_oiio.cpp is not in the archive: it is the module $(BUILD)/btf_image_oiio.so
#               (OpenImageIO and its 260 libraries), which btf_image.c loads on the first
#               image call (codec/image/btf_image_module.h), so no program maps them at start
CODEC_PKGS  := libcjson lapacke openblas zlib qhull_r libwebp libavif
IMAGE_PKGS  := OpenImageIO
CODEC_ROOMS := common image format input decompress compress
CODEC_OBJ   := $(foreach r,$(CODEC_ROOMS),$(patsubst %.c,$(BUILD)/%.o,$(wildcard codec/$(r)/*.c)))
IMAGE_MOD   := $(BUILD)/btf_image_oiio.so
IMAGE_MOD_OBJ := $(BUILD)/codec/image/btf_image_oiio.pic.o
CODEC_LIB   := $(BUILD)/codec/libbtfcodec.a
# $(call codec_inc,ROOMS): -I for the public headers and for these inner rooms.
codec_inc    = -Icodec/include $(addprefix -Icodec/,$(1))
CODEC_INNER := $(call codec_inc,$(CODEC_ROOMS))
$(CODEC_OBJ): PKG_CFLAGS = $(call pkg,--cflags,$(CODEC_PKGS))
$(BUILD)/codec/common/%.o:     INC := $(call codec_inc,common)
$(BUILD)/codec/image/%.o:      INC := $(call codec_inc,common image)
$(BUILD)/codec/format/%.o:     INC := $(call codec_inc,common image format)
$(BUILD)/codec/input/%.o:      INC := $(call codec_inc,common image input)
$(BUILD)/codec/decompress/%.o: INC := $(call codec_inc,common image format decompress)
$(BUILD)/codec/compress/%.o:   INC := $(call codec_inc,common image format decompress compress)
$(IMAGE_MOD_OBJ): INC := $(call codec_inc,common image)
$(IMAGE_MOD_OBJ): PKG_CFLAGS = $(call pkg,--cflags,$(IMAGE_PKGS) libwebp libavif)
# where an installed program's library finds the module when not beside the program
$(BUILD)/codec/image/btf_image.o: PKG_CFLAGS += -DBTF_IMAGE_MODULE_DIR='"$(PREFIX)/lib/btfcodec"'

# bench/gen/    synthetic materials with ground truth (uses codec)
GEN_OBJ    := $(patsubst %.c,$(BUILD)/%.o,$(wildcard bench/gen/*.c))
GEN_LIB    := $(BUILD)/bench/gen/libbtfgen.a
$(GEN_OBJ): INC := $(call codec_inc,common) -Ibench/gen

# shaders/host/ headless GL host of shaders/: EGL and OSMesa backends, package upload, render,
#               glTF models (tinygltf, btf_gltf.cpp) (uses codec)
GL_PKGS    := osmesa egl glesv2 tinygltf
GL_OBJ     := $(patsubst %.c,$(BUILD)/%.o,$(wildcard shaders/host/*.c)) $(patsubst %.cpp,$(BUILD)/%.o,$(wildcard shaders/host/*.cpp))
GL_LIB     := $(BUILD)/shaders/host/libbtfgl.a
$(GL_OBJ): INC := $(call codec_inc,common image) -Ishaders/host
$(GL_OBJ): PKG_CFLAGS = $(call pkg,--cflags,$(GL_PKGS) libcjson)

# bench/eval/   method families, thesis-format export, chart data (uses codec, shaders/host)
EVAL_OBJ   := $(patsubst %.c,$(BUILD)/%.o,$(wildcard bench/eval/*.c))
EVAL_LIB   := $(BUILD)/bench/eval/libbtfeval.a
$(EVAL_OBJ): INC := $(CODEC_INNER) -Ishaders/host -Ibench/eval
$(EVAL_OBJ): PKG_CFLAGS = $(call pkg,--cflags,libcjson gsl)

# tools/        the `btf` command line (uses every room above)
ALL_INC    := $(CODEC_INNER) -Ibench/gen -Ishaders/host -Ibench/eval -Itools
TOOLS_OBJ  := $(patsubst %.c,$(BUILD)/%.o,$(filter-out tools/btf_main.c,$(wildcard tools/*.c)))
TOOLS_LIB  := $(BUILD)/tools/libbtftools.a
BTF_BIN    := $(BUILD)/btf
ALL_CFLAGS  = $(call pkg,--cflags,$(CODEC_PKGS) $(GL_PKGS) gsl)
$(TOOLS_OBJ) $(BUILD)/tools/btf_main.o: INC := $(ALL_INC)
$(TOOLS_OBJ) $(BUILD)/tools/btf_main.o: PKG_CFLAGS = $(ALL_CFLAGS)

# client/       the browser viewer; $(BUILD)/client/ its one-file bundle (esbuild, the
#               "render" shaders inside) and the pages, what btfd serves in `make demo`
BUNDLE     := $(BUILD)/client/btf-viewer.js
$(BUNDLE): $(wildcard client/*) $(wildcard client/pages/*) $(wildcard shaders/*.*) tools/bundle.mjs package-lock.json
	@test -x node_modules/.bin/esbuild || { echo "esbuild is missing: run 'make setup' (npm ci)"; exit 1; }
	node tools/bundle.mjs $(BUILD)/client

# tests/        Criterion suites (one binary), one folder per room they test (tests/ROOM/), and
#               their shared fixtures (tests/fixtures.h); not deploy/ (its own program) or e2e/ (browser)
TEST_OBJ   := $(patsubst %.c,$(BUILD)/%.o,$(filter-out tests/deploy/%,$(wildcard tests/*.c tests/*/*.c)))
TEST_BIN   := $(BUILD)/run_tests
$(TEST_OBJ): INC := $(ALL_INC) -Itests
$(TEST_OBJ): PKG_CFLAGS = $(ALL_CFLAGS) $(call pkg,--cflags,criterion libwebsockets)
# the image test knows when the build links the image module at start (IMAGE_AT_START)
$(BUILD)/tests/codec/test_image.o: PKG_CFLAGS += $(if $(IMAGE_AT_START),-DBTF_IMAGE_AT_START=1)

ROOM_LIBS  := $(TOOLS_LIB) $(EVAL_LIB) $(GL_LIB) $(GEN_LIB) $(CODEC_LIB)
# (a sanitizer build's programs link the image module: IMAGE_AT_START below)
LINK_DEPS   = $(if $(SAN),$(IMAGE_MOD))
# Sanitizer builds link the image module at start (dlopen then finds it loaded): gcc 12's
# LeakSanitizer crashes ("Tracer caught signal 11") scanning the dynamic TLS of a library
# opened later, as OpenImageIO's are; loaded at start their TLS is static.
# $(call image_at_start,DIR): the link words for DIR's module (the libFuzzer links use it too).
image_at_start = $(abspath $(1))/btf_image_oiio.so -Xlinker -rpath -Xlinker $(abspath $(1))
IMAGE_AT_START = $(if $(SAN),$(call image_at_start,$(BUILD)))
LINK_LIBS   = $(call pkg,--libs,$(CODEC_PKGS) $(GL_PKGS) gsl) -lstdc++ -lm -lpthread $(IMAGE_AT_START)
TEST_LIBS   = $(call pkg,--libs,criterion libwebsockets)

.PHONY: all setup build test e2e check asan bench bench-gpu chart figure demo clean lib install uninstall
all: build
build: $(ROOM_LIBS) $(BTF_BIN) $(TEST_BIN) $(BUNDLE) $(IMAGE_MOD)
lib: $(CODEC_LIB)
# The library under its documented name, for programs outside this tree
# (the default build only: sanitizer builds keep theirs in their own folder).
codec/libbtfcodec.a: $(CODEC_LIB)
	cp $< $@
ifeq ($(BUILD),build)
build: codec/libbtfcodec.a
endif

setup:
	@bash tools/setup.sh

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(INC) $(PKG_CFLAGS) -c $< -o $@

$(BUILD)/%.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) $(INC) $(PKG_CFLAGS) -c $< -o $@

$(BUILD)/%.pic.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) -fPIC -fvisibility=hidden $(INC) $(PKG_CFLAGS) -c $< -o $@

$(IMAGE_MOD): $(IMAGE_MOD_OBJ)
	$(CXX) $(LDFLAGS) -shared -o $@ $^ $(call pkg,--libs,$(IMAGE_PKGS)) -lstdc++ -lm

$(BUILD)/%.a:
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^
$(CODEC_LIB): $(CODEC_OBJ)
$(GEN_LIB): $(GEN_OBJ)
$(GL_LIB): $(GL_OBJ)
$(EVAL_LIB): $(EVAL_OBJ)
$(TOOLS_LIB): $(TOOLS_OBJ)

$(BTF_BIN): $(BUILD)/tools/btf_main.o $(ROOM_LIBS) | $(LINK_DEPS)
	$(CXX) $(LDFLAGS) -o $@ $^ $(LINK_LIBS)

$(TEST_BIN): $(TEST_OBJ) $(ROOM_LIBS) | $(LINK_DEPS)
	$(CXX) $(LDFLAGS) -o $@ $^ $(TEST_LIBS) $(LINK_LIBS)

# The suites run two test processes at a time (--jobs 2), each on one OpenMP (and
# OpenBLAS) thread: the two processes already keep both cores busy, and a second
# thread in each only contends for them (the cli suite took 2.6x the CPU time with
# it). The tests of threaded code set their own count (test_package.c, test_rd.c).
TEST_ENV := OMP_NUM_THREADS=1

# Every test; Criterion prints the "Synthesis: Tested: N | Passing: N | Failing: N" line.
# The build takes every core unless make was given -j (then its jobserver decides).
test: setup
	$(MAKE) $(if $(filter -j%,$(MAKEFLAGS)),,-j$(shell nproc)) build
	bash tools/check_rooms.sh $(BUILD)
	$(TEST_ENV) $(TEST_BIN) --jobs 2
	bash tests/install_test.sh
	BUILD=$(BUILD) bash tests/deploy_test.sh
	$(MAKE) e2e

# Browser tests: playwright-core driving Debian's chromium against a real btfd. The files
# that judge time on an emulated link (E2E_TIMED) run one at a time on an otherwise idle
# host, then the others two at a time (they wait on the browser more than they compute:
# 0.84 of a core at two files at a time); both groups always run, either failing fails.
E2E_TIMED := tests/e2e/embed.test.mjs tests/e2e/field.test.mjs tests/e2e/static.test.mjs tests/e2e/client.test.mjs
e2e:
	@st=0; node --test --test-concurrency=1 $(E2E_TIMED) || st=1; \
	node --test --test-concurrency=2 $(filter-out $(E2E_TIMED),$(wildcard tests/e2e/*.test.mjs)) || st=1; exit $$st

# Quick subset: the rooms check, then every suite but those whose name starts with "slow".
check: build
	bash tools/check_rooms.sh $(BUILD)
	$(TEST_ENV) $(TEST_BIN) --jobs 2 --filter '!(slow*)'

# Every sanitizer report of every process the suites start (btf, btfd, the test
# runner; a test may swallow a child's stderr) goes to a file under ASAN_REPORTS, and
# the run fails when any was written (tests/asan_reports.sh prints them). First the
# canary (tests/test_sanitizer.c): a leak made on purpose inside a test process must
# be reported, or tests/lsan.supp hides what the suites would leak.
ASAN_REPORTS := build-asan/reports
asan_env = ASAN_OPTIONS=detect_leaks=1:log_path=$(CURDIR)/$(1)/asan \
    LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp:print_suppressions=0 \
    UBSAN_OPTIONS=print_stacktrace=1:log_path=$(CURDIR)/$(1)/ubsan
ASAN_ENV = $(call asan_env,$(ASAN_REPORTS))
asan: setup
	$(MAKE) BUILD=build-asan OPT='-O1 -g -fno-omit-frame-pointer' \
	    SAN='-fsanitize=address,undefined -fno-sanitize-recover=undefined' build
	rm -rf $(ASAN_REPORTS) && mkdir -p $(ASAN_REPORTS)/canary
	$(call asan_env,$(ASAN_REPORTS)/canary) BTF_LEAK_CANARY=1 build-asan/run_tests --filter 'sanitizer/*' >/dev/null 2>&1; \
	    bash tests/asan_reports.sh --canary $(ASAN_REPORTS)/canary
	$(ASAN_ENV) BTF_BUILD=$(CURDIR)/build-asan build-asan/run_tests --jobs 2 || { bash tests/asan_reports.sh $(ASAN_REPORTS); exit 1; }
	$(ASAN_ENV) $(MAKE) BUILD=build-asan e2e || { bash tests/asan_reports.sh $(ASAN_REPORTS); exit 1; }
	bash tests/asan_reports.sh $(ASAN_REPORTS)

# bench/        benchmark programs (one per bench/bench_*.c) and scripts
BENCH_BIN := $(patsubst bench/%.c,$(BUILD)/bench/%,$(wildcard bench/*.c))
$(BENCH_BIN:%=%.o): INC := $(ALL_INC)
$(BENCH_BIN:%=%.o): PKG_CFLAGS = $(ALL_CFLAGS)
$(BUILD)/bench/%: $(BUILD)/bench/%.o $(ROOM_LIBS) | $(LINK_DEPS)
	$(CXX) $(LDFLAGS) -o $@ $^ $(LINK_LIBS)

bench: setup
	$(MAKE) build $(BENCH_BIN)
	@mkdir -p bench/results
	bash bench/run.sh
	bash bench/plot_lod.sh

# The shader bench as a self-contained folder for a machine with only a GPU driver
# (build/bench-gpu/: bench/gpu/build.sh; run there with build/bench-gpu/run.sh).
bench-gpu: setup
	$(MAKE) build $(BUILD)/bench/bench_shader
	BUILD=$(BUILD) bash bench/gpu/build.sh

# The speed/accuracy charts (doc/figures/chart-*) and the stability table (doc/figures/stability.md).
chart: setup
	$(MAKE) build
	$(BTF_BIN) chart gen:knit gen:tiles gen:stone \
	    $(wildcard $(SHARED)/data/thesis-ubo2003/wool $(SHARED)/data/thesis-ubo2003/corduroy) \
	    --size 32 --stream-size 64 --out doc/figures
	BTF_STABILITY_OUT=$(CURDIR)/doc/figures/stability.md $(TEST_BIN) --jobs 2 --filter 'stability/*'

# The README's product under the built-in studio environment (doc/figures/product-studio.png),
# and the library page and the 1-chunk-against-all picture the browser tests take.
figure: setup
	$(MAKE) build
	bash tools/figure.sh
	BTF_FIGURES_OUT=$(CURDIR)/doc/figures node --test tests/e2e/client.test.mjs

demo: setup build
	bash tools/demo.sh

clean:
	rm -rf build build-asan codec/libbtfcodec.a

# --- make install / uninstall: PREFIX (default /usr/local), DESTDIR for staging ---
# bin/btf, bin/btfd, lib/libbtfcodec.a, include/btfcodec/ (codec/include/*.h),
# lib/pkgconfig/btfcodec.pc, and under share/btf-stream/ the browser client and
# the shader files it loads (what an installed btfd serves by default).
PREFIX       ?= /usr/local
DESTDIR      ?=
PC_VERSION   := $(shell sed -n 's/.*define BTF_VERSION "\(.*\)".*/\1/p' codec/include/btf_version.h)
INST_ROOT     = $(DESTDIR)$(PREFIX)
INST_HEADERS := $(wildcard codec/include/*.h)
INST_CLIENT  := $(wildcard client/*.*)
INST_PAGES   := $(wildcard client/pages/*.*)
INST_SHADERS := $(wildcard shaders/*.glsl shaders/*.vert shaders/*.frag) shaders/manifest.json
INST_FILES    = bin/btf bin/btfd lib/libbtfcodec.a lib/btfcodec/btf_image_oiio.so lib/pkgconfig/btfcodec.pc \
    $(INST_HEADERS:codec/include/%=include/btfcodec/%) $(addprefix share/btf-stream/,$(INST_CLIENT) $(INST_SHADERS)) \
    $(INST_PAGES:client/pages/%=share/btf-stream/client/%)

install: $(BTF_BIN) $(BUILD)/btfd $(CODEC_LIB) $(IMAGE_MOD)
	install -D -m 755 $(BTF_BIN) $(INST_ROOT)/bin/btf
	install -D -m 755 $(BUILD)/btfd $(INST_ROOT)/bin/btfd
	install -D -m 644 $(CODEC_LIB) $(INST_ROOT)/lib/libbtfcodec.a
	install -D -m 755 $(IMAGE_MOD) $(INST_ROOT)/lib/btfcodec/btf_image_oiio.so
	install -D -m 644 -t $(INST_ROOT)/include/btfcodec $(INST_HEADERS)
	install -D -m 644 -t $(INST_ROOT)/share/btf-stream/client $(INST_CLIENT) $(INST_PAGES)
	install -D -m 644 -t $(INST_ROOT)/share/btf-stream/shaders $(INST_SHADERS)
	install -d -m 755 $(INST_ROOT)/lib/pkgconfig
	printf '%s\n' 'prefix=$(PREFIX)' 'libdir=$${prefix}/lib' 'includedir=$${prefix}/include' '' \
	    'Name: btfcodec' 'Description: BTF material compression by k-view PCA and streamable packages' \
	    'Version: $(PC_VERSION)' 'Requires.private: $(CODEC_PKGS)' 'Cflags: -I$${includedir}/btfcodec' \
	    'Libs: -L$${libdir} -lbtfcodec' 'Libs.private: -lstdc++ -lm -lgomp' > $(INST_ROOT)/lib/pkgconfig/btfcodec.pc

uninstall:
	rm -f $(addprefix $(INST_ROOT)/,$(INST_FILES))
	rmdir $(addprefix $(INST_ROOT)/,share/btf-stream/client share/btf-stream/shaders share/btf-stream include/btfcodec lib/btfcodec) 2>/dev/null || true

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
include server/build.mk
include fuzz/build.mk

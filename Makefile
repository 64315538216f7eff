# btf-stream: compress measured BTFs by k-view PCA and stream them to WebGL2.
# Targets: setup all test check asan bench demo clean (see README.md).

SHELL    := /bin/bash
BUILD    ?= build
SHARED   ?= $(abspath $(CURDIR)/../shared)
export BTF_SHARED := $(SHARED)
export BTF_ROOT := $(CURDIR)

CC       ?= cc
CXX      ?= g++
OPT      ?= -O2 -g
WARN     := -Wall -Wextra -Werror
CFLAGS   += -std=c11 $(WARN) $(OPT) -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L -MMD -MP
CXXFLAGS += -std=c++17 $(WARN) $(OPT) -MMD -MP
SAN      ?=
CFLAGS   += $(SAN)
CXXFLAGS += $(SAN)
LDFLAGS  += $(SAN)

PKGS     := OpenImageIO libcjson lapacke openblas osmesa egl glesv2
PKG_CFLAGS = $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   = $(shell pkg-config --libs $(PKGS) 2>/dev/null)
TEST_LIBS  = $(shell pkg-config --libs criterion libwebsockets 2>/dev/null)

CODEC_C   := $(wildcard codec/*.c)
CODEC_CXX := $(wildcard codec/*.cpp)
CODEC_OBJ := $(CODEC_C:%.c=$(BUILD)/%.o) $(CODEC_CXX:%.cpp=$(BUILD)/%.o)
CODEC_LIB := $(BUILD)/codec/libbtfcodec.a

TOOLS_C   := $(filter-out tools/btf_main.c,$(wildcard tools/*.c))
TOOLS_OBJ := $(TOOLS_C:%.c=$(BUILD)/%.o)
BTF_BIN   := $(BUILD)/btf

TEST_C    := $(wildcard tests/*.c)
TEST_OBJ  := $(TEST_C:%.c=$(BUILD)/%.o)
TEST_BIN  := $(BUILD)/run_tests

INC       := -Icodec -Itools
LINK_LIBS  = $(PKG_LIBS) -lgsl -lstdc++ -lm -lpthread

.PHONY: all setup build test e2e check asan bench chart demo clean lib
all: build
build: $(CODEC_LIB) $(BTF_BIN) $(TEST_BIN)
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

$(CODEC_LIB): $(CODEC_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BTF_BIN): $(BUILD)/tools/btf_main.o $(TOOLS_OBJ) $(CODEC_LIB)
	$(CXX) $(LDFLAGS) -o $@ $^ $(LINK_LIBS)

$(TEST_BIN): $(TEST_OBJ) $(TOOLS_OBJ) $(CODEC_LIB)
	$(CXX) $(LDFLAGS) -o $@ $^ $(TEST_LIBS) $(LINK_LIBS)

# Every test; Criterion prints the "Synthesis: Tested: N | Passing: N | Failing: N" line.
test: setup
	$(MAKE) build
	$(TEST_BIN) --jobs 2
	$(MAKE) e2e

# Browser tests: playwright-core driving Debian's chromium against a real btfd.
e2e:
	node --test --test-concurrency=1 tests/e2e/

# Quick subset: skips suites whose name starts with "slow".
check: build
	$(TEST_BIN) --jobs 2 --filter '!(slow*)'

asan: setup
	$(MAKE) BUILD=build-asan OPT='-O1 -g -fno-omit-frame-pointer' \
	    SAN='-fsanitize=address,undefined -fno-sanitize-recover=undefined' build
	ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp UBSAN_OPTIONS=print_stacktrace=1 build-asan/run_tests --jobs 2

BENCH_C   := $(wildcard bench/*.c)
BENCH_BIN := $(BENCH_C:bench/%.c=$(BUILD)/bench/%)
$(BUILD)/bench/%: $(BUILD)/bench/%.o $(TOOLS_OBJ) $(CODEC_LIB)
	$(CXX) $(LDFLAGS) -o $@ $^ $(LINK_LIBS)

bench: setup
	$(MAKE) build $(BENCH_BIN)
	@mkdir -p bench/results
	bash bench/run.sh
	bash bench/plot_lod.sh

# The speed/accuracy charts (doc/chart-*) and the stability table (doc/stability.md).
chart: setup
	$(MAKE) build
	$(BTF_BIN) chart gen:knit gen:tiles gen:stone \
	    $(wildcard $(SHARED)/data/thesis-ubo2003/wool $(SHARED)/data/thesis-ubo2003/corduroy) \
	    --size 32 --stream-size 64 --out doc
	$(TEST_BIN) --jobs 2 --filter 'stability/*'

demo: setup build
	bash tools/demo.sh

clean:
	rm -rf build build-asan codec/libbtfcodec.a

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
include server/build.mk

# fuzz/build.mk - the fuzz targets of every reader. Included from the top Makefile.
#
#   $(BUILD)/fuzz/replay_NAME   fuzz/fuzz_NAME.c + fuzz/replay_main.c with gcc: replays
#                               fuzz/corpus/NAME/* (built by `make build`, run by `make test`)
#   make fuzz [FUZZ_SECONDS=N]  libFuzzer + ASan/UBSan builds (clang, build-fuzz/) of every
#                               target, each run for FUZZ_SECONDS, growing fuzz/corpus/NAME
#   make fuzz-replay            replays every corpus (also part of `make test` via the suite "fuzz")
#
# Targets: dirset (direction-set JSON), dfmf (.btf files), manifest (package
# manifest), package (package files: textures, weights, 8-bit weights, manifest),
# thesis (thesis packages), ubo2003_name (image file names), roundtrip (random
# small BTFs through compress + read + decode), gltf (glTF models of the GL host,
# shaders/host/btf_gltf.cpp), hdr (environment images, shaders/host/btf_env.c),
# request (btfd's request parser, server/build.mk).

FUZZ_CODEC        := dirset dfmf manifest package thesis ubo2003_name roundtrip gltf hdr
FUZZ_CODEC_OBJ    := $(FUZZ_CODEC:%=$(BUILD)/fuzz/fuzz_%.o) $(BUILD)/fuzz/replay_main.o
FUZZ_CODEC_REPLAY := $(FUZZ_CODEC:%=$(BUILD)/fuzz/replay_%)
FUZZ_LINK          = $(call pkg,--libs,$(CODEC_PKGS) $(GL_PKGS)) -lstdc++ -lm
FUZZ_BUILD        ?= build-fuzz
FUZZ_RSS_MB       ?= 2048

$(FUZZ_CODEC_OBJ): INC := $(CODEC_INNER) -Ibench/gen -Ishaders/host -Ifuzz
$(FUZZ_CODEC_OBJ): PKG_CFLAGS = $(call pkg,--cflags,$(CODEC_PKGS))
build: $(FUZZ_CODEC_REPLAY)

$(BUILD)/fuzz/replay_%: $(BUILD)/fuzz/fuzz_%.o $(BUILD)/fuzz/replay_main.o $(GL_LIB) $(GEN_LIB) $(CODEC_LIB)
	$(CXX) $(LDFLAGS) -o $@ $^ $(FUZZ_LINK)

.PHONY: fuzz fuzz-replay fuzz-codec
fuzz-replay: $(FUZZ_CODEC_REPLAY) $(FUZZ_REPLAY)
	@for t in $(FUZZ_CODEC); do $(BUILD)/fuzz/replay_$$t fuzz/corpus/$$t || exit 1; done
	$(FUZZ_REPLAY) fuzz/corpus/request

# libFuzzer builds: the codec and generator rebuilt with clang and the sanitizers
# (warnings kept, not fatal: clang's differ from gcc's), then one run per target.
# Leaks inside third-party libraries are suppressed by tests/lsan.supp (full
# stacks, so a suppression can see the library frame).
fuzz-codec:
	$(MAKE) BUILD=$(FUZZ_BUILD) CC=clang CXX=clang++ OPT='-O1 -g' WARN='-Wall -Wextra' \
	    SAN='-fsanitize=address,undefined,fuzzer-no-link' \
	    $(FUZZ_BUILD)/codec/libbtfcodec.a $(FUZZ_BUILD)/bench/gen/libbtfgen.a \
	    $(FUZZ_BUILD)/shaders/host/libbtfgl.a $(FUZZ_CODEC:%=$(FUZZ_BUILD)/fuzz/fuzz_%.o)
	@for t in $(FUZZ_CODEC); do \
	    clang++ -fsanitize=fuzzer,address,undefined -fopenmp -o $(FUZZ_BUILD)/fuzz/fuzz_$$t \
	        $(FUZZ_BUILD)/fuzz/fuzz_$$t.o $(FUZZ_BUILD)/shaders/host/libbtfgl.a $(FUZZ_BUILD)/bench/gen/libbtfgen.a \
	        $(FUZZ_BUILD)/codec/libbtfcodec.a \
	        $(FUZZ_LINK) || exit 1; \
	done
	@mkdir -p $(FUZZ_BUILD)/fuzz/log
	@for t in $(FUZZ_CODEC); do \
	    echo "fuzz: $$t for $(FUZZ_SECONDS) s"; \
	    (cd $(FUZZ_BUILD)/fuzz && ASAN_OPTIONS=fast_unwind_on_malloc=0 \
	        LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp ./fuzz_$$t -max_total_time=$(FUZZ_SECONDS) -rss_limit_mb=$(FUZZ_RSS_MB) \
	        -malloc_limit_mb=$(FUZZ_RSS_MB) -max_len=65536 -print_final_stats=1 \
	        $(CURDIR)/fuzz/corpus/$$t > log/$$t.txt 2>&1) || { tail -40 $(FUZZ_BUILD)/fuzz/log/$$t.txt; exit 1; }; \
	    grep -E "stat::number_of_executed_units|cov:" $(FUZZ_BUILD)/fuzz/log/$$t.txt | tail -2; \
	done

fuzz: fuzz-codec fuzz-request

# fuzz/build.mk - the fuzz targets of every reader. Included from the top Makefile.
#
#   $(BUILD)/fuzz/replay_NAME   fuzz/fuzz_NAME.c + fuzz/replay_main.c with gcc: replays
#                               fuzz/corpus/NAME/* (built by `make build`, run by `make test`)
#   make fuzz                   libFuzzer + ASan/UBSan builds (clang, build-fuzz/) of every
#                               target, then fuzz/run.sh runs them one at a time, growing
#                               fuzz/corpus/NAME, and prints one table: executions, seconds,
#                               executions per second, coverage (cov, ft), corpus size;
#                               the table is also written to build-fuzz/fuzz/summary.txt
#                               (FUZZ_SUMMARY; fuzz-deep: summary-deep.txt), the logs to
#                               build-fuzz/fuzz/log/NAME.txt
#     FUZZ_SECONDS=N            each target's time bound (default 60)
#     FUZZ_RUNS=N               and an execution bound: -runs=N, whichever comes first (0: none)
#     FUZZ_TARGETS='a b'        only these targets, in this order (default: all, request
#                               included, the quickest first: FUZZ_ORDER)
#     FUZZ_TMPDIR=DIR           the disk targets' scratch (default /dev/shm where it exists)
#     FUZZ_CORPUS=DIR           the corpora's root instead of fuzz/corpus (a copy: measure
#                               without growing the saved corpora)
#     FUZZ_FLAGS=...            more libFuzzer flags for every target (e.g. -entropic=0)
#     FUZZ_THREADS=N            OpenMP and OpenBLAS threads of each target (default 1)
#     FUZZ_NICE=N               run each target under nice -n N (default: not)
#     FUZZ_JOBS=N               N targets at a time (fuzz/parallel.sh; default 1, fuzz-deep:
#                               every core), each on one core
#     FUZZ_FORK=N               each target in libFuzzer's fork mode, N worker processes
#                               (default 0: one process); with FUZZ_JOBS=1, a slow target
#                               on every core: make fuzz-deep FUZZ_TARGETS=gltf FUZZ_JOBS=1
#                               FUZZ_FORK=2 (FUZZ_RUNS counts every worker's executions)
#     FUZZ_ASAN_OPTIONS=...     ASan's options (fast_unwind_on_malloc=0: full allocation
#                               stacks, at a 30th of the speed; fuzz/run.sh's header)
#     FUZZ_SAN=undefined        the sanitizers of the libFuzzer build (default
#                               address,undefined; UB always stops a run: no recovery).
#                               Without ASan a slow target runs faster, for depth, in its
#                               own folder, its corpus then replayed under ASan:
#                               make fuzz-deep FUZZ_BUILD=build-fuzz-ub FUZZ_SAN=undefined ...
#                               then build-fuzz/fuzz/fuzz_NAME -runs=0 DIR (doc/cli.md 12.1)
#     (per target)              -max_len (the largest input its format needs) and its own
#                               libFuzzer flags and environment: fuzz/run.sh, target_settings
#   make fuzz-deep              the deep run: every target to FUZZ_DEEP_RUNS (default 10 M)
#                               executions or FUZZ_DEEP_SECONDS (default 3600) each, whichever
#                               comes first, under nice -n 19, one target per core, on a copy
#                               of the corpora in $(FUZZ_BUILD)/deep-corpus (made from
#                               fuzz/corpus on the first run, kept and grown by later ones):
#                               the saved corpora stay small, as `make test` replays them
#   make fuzz-replay            replays every corpus (also part of `make test` via the suite "fuzz")
#
# Targets: dirset (direction-set JSON), dfmf (.btf files), manifest (package
# manifest), package (package files on disk: textures, weights, 8-bit weights,
# manifest), package_mem (the same files read from memory, btf_package_read_with),
# thesis (thesis packages on disk), thesis_mem (the same from memory),
# ubo2003_name (image file names), roundtrip (random tiny BTFs through compress +
# read + decode, the package held in memory: the writer's sink, no file system call),
# gltf (glTF models of the GL host, shaders/host/btf_gltf.cpp), hdr (environment
# images, shaders/host/btf_env.c), request (btfd's request parser, server/build.mk).

FUZZ_CODEC        := dirset dfmf manifest package package_mem thesis thesis_mem ubo2003_name roundtrip gltf hdr
FUZZ_CODEC_OBJ    := $(FUZZ_CODEC:%=$(BUILD)/fuzz/fuzz_%.o) $(BUILD)/fuzz/replay_main.o
FUZZ_CODEC_REPLAY := $(FUZZ_CODEC:%=$(BUILD)/fuzz/replay_%)
FUZZ_LINK          = $(call pkg,--libs,$(CODEC_PKGS) $(GL_PKGS)) -lstdc++ -lm $(IMAGE_AT_START)
FUZZ_BUILD        ?= build-fuzz
FUZZ_RSS_MB       ?= 2048
FUZZ_SAN          ?= address,undefined

$(FUZZ_CODEC_OBJ): INC := $(CODEC_INNER) -Ibench/gen -Ishaders/host -Ifuzz
$(FUZZ_CODEC_OBJ): PKG_CFLAGS = $(call pkg,--cflags,$(CODEC_PKGS))
build: $(FUZZ_CODEC_REPLAY)

$(BUILD)/fuzz/replay_%: $(BUILD)/fuzz/fuzz_%.o $(BUILD)/fuzz/replay_main.o $(GL_LIB) $(GEN_LIB) $(CODEC_LIB) | $(LINK_DEPS)
	$(CXX) $(LDFLAGS) -o $@ $^ $(FUZZ_LINK)

.PHONY: fuzz fuzz-deep fuzz-replay fuzz-codec
fuzz-replay: $(FUZZ_CODEC_REPLAY) $(FUZZ_REPLAY)
	@for t in $(FUZZ_CODEC); do $(BUILD)/fuzz/replay_$$t fuzz/corpus/$$t || exit 1; done
	$(FUZZ_REPLAY) fuzz/corpus/request

# libFuzzer builds: the codec and generator rebuilt with clang and the sanitizers
# (warnings kept, not fatal: clang's differ from gcc's), one binary per target.
# Leaks inside third-party libraries are suppressed by tests/lsan.supp (full
# stacks, so a suppression can see the library frame). -O1: -O2 was measured
# (15 s a target, executions per CPU second) and gains nothing overall: dirset
# +42 %, gltf +7 %, roundtrip +11 %, but manifest -19 %, package_mem -11 %,
# dfmf -9 %, package -5 %.
fuzz-codec:
	$(MAKE) BUILD=$(FUZZ_BUILD) CC=clang CXX=clang++ OPT='-O1 -g' WARN='-Wall -Wextra' \
	    SAN='-fsanitize=$(FUZZ_SAN),fuzzer-no-link -fno-sanitize-recover=undefined' \
	    $(FUZZ_BUILD)/codec/libbtfcodec.a $(FUZZ_BUILD)/btf_image_oiio.so $(FUZZ_BUILD)/bench/gen/libbtfgen.a \
	    $(FUZZ_BUILD)/shaders/host/libbtfgl.a $(FUZZ_CODEC:%=$(FUZZ_BUILD)/fuzz/fuzz_%.o)
	@for t in $(FUZZ_CODEC); do \
	    clang++ -fsanitize=fuzzer,$(FUZZ_SAN) -fno-sanitize-recover=undefined -fopenmp -o $(FUZZ_BUILD)/fuzz/fuzz_$$t \
	        $(FUZZ_BUILD)/fuzz/fuzz_$$t.o $(FUZZ_BUILD)/shaders/host/libbtfgl.a $(FUZZ_BUILD)/bench/gen/libbtfgen.a \
	        $(FUZZ_BUILD)/codec/libbtfcodec.a \
	        $(FUZZ_LINK) $(call image_at_start,$(FUZZ_BUILD)) || exit 1; \
	done

# the order targets run in: the quickest to 10 M executions first (so a deep run cut
# short has the most targets done), then any target not named here
FUZZ_ORDER   := ubo2003_name request thesis_mem thesis hdr dirset package_mem dfmf package manifest gltf roundtrip
FUZZ_TARGETS ?= $(FUZZ_ORDER) $(filter-out $(FUZZ_ORDER),$(FUZZ_CODEC) request)
FUZZ_RUNS    ?= 0
FUZZ_TMPDIR  ?= $(if $(wildcard /dev/shm/.),/dev/shm,/tmp)
FUZZ_CORPUS  ?= fuzz/corpus
FUZZ_SUMMARY ?= $(FUZZ_BUILD)/fuzz/summary.txt
FUZZ_THREADS ?= 1
FUZZ_NICE    ?=
FUZZ_DEEP_RUNS    ?= 10000000
FUZZ_DEEP_SECONDS ?= 3600
FUZZ_JOBS         ?=
FUZZ_FORK         ?= 0

fuzz: fuzz-codec fuzz-request
	FUZZ_SECONDS=$(FUZZ_SECONDS) FUZZ_RUNS=$(FUZZ_RUNS) FUZZ_RSS_MB=$(FUZZ_RSS_MB) FUZZ_TMPDIR=$(FUZZ_TMPDIR) \
	    FUZZ_ASAN_OPTIONS='$(FUZZ_ASAN_OPTIONS)' FUZZ_FLAGS='$(FUZZ_FLAGS)' FUZZ_CORPUS=$(FUZZ_CORPUS) \
	    FUZZ_THREADS=$(FUZZ_THREADS) FUZZ_NICE=$(FUZZ_NICE) FUZZ_SUMMARY=$(FUZZ_SUMMARY) FUZZ_JOBS=$(FUZZ_JOBS) \
	    FUZZ_FORK=$(FUZZ_FORK) \
	    bash fuzz/$(if $(filter-out 0 1,$(FUZZ_JOBS)),parallel.sh,run.sh) $(FUZZ_BUILD) $(FUZZ_TARGETS)

# The deep run: make fuzz with other defaults, on a copy of the corpora.
fuzz-deep:
	@test -d $(FUZZ_BUILD)/deep-corpus || { mkdir -p $(FUZZ_BUILD) && cp -r fuzz/corpus $(FUZZ_BUILD)/deep-corpus; }
	$(MAKE) fuzz FUZZ_RUNS=$(FUZZ_DEEP_RUNS) FUZZ_SECONDS=$(FUZZ_DEEP_SECONDS) FUZZ_NICE=$(or $(FUZZ_NICE),19) \
	    FUZZ_JOBS=$(or $(FUZZ_JOBS),$(shell nproc)) \
	    FUZZ_CORPUS=$(FUZZ_BUILD)/deep-corpus FUZZ_SUMMARY=$(FUZZ_BUILD)/fuzz/summary-deep.txt

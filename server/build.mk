# server/build.mk - builds the btfd streaming server and the request-parser fuzzers.
# Included from the top Makefile (after its variables): `include server/build.mk`.
# Before that, standalone:  make BUILD=build-x -f Makefile -f server/build.mk build-x/btfd
#
# Targets:
#   $(BUILD)/btfd                 the server (server/*.c + $(CODEC_LIB), libwebsockets, cJSON)
#   $(BUILD)/fuzz_request_replay  replays fuzz/corpus/request/* through the parser (cc)
#   fuzz-request                  libFuzzer build (clang): build-fuzz/fuzz/fuzz_request
# (`make fuzz` runs it with the codec targets, fuzz/build.mk, and replays every corpus)
#   $(BUILD)/resume_clients       the reconnecting load client of tests/deploy_test.sh (nginx + 2 btfd)
# server/ uses codec/ only: its public headers and common/ (error formatting).
# `build` gains btfd and the replay binary, so `make test` runs the server tests
# (tests/server/test_server.c starts $(BTF_BUILD)/btfd) and the corpus replay.

SERVER_C     := $(wildcard server/*.c)
SERVER_OBJ   := $(SERVER_C:%.c=$(BUILD)/%.o)
BTFD_BIN     := $(BUILD)/btfd
SERVER_CFLAGS = $(call pkg,--cflags,libwebsockets libcjson libcrypto)
SERVER_LIBS   = $(call pkg,--libs,libwebsockets libcjson libcrypto)
FUZZ_LIBS     = $(call pkg,--libs,libcjson)

FUZZ_REPLAY  := $(BUILD)/fuzz_request_replay
FUZZ_SECONDS ?= 60
FUZZ_SRC     := fuzz/fuzz_request.c server/btfd_request.c

export BTF_BUILD := $(abspath $(BUILD))

RESUME_BIN   := $(BUILD)/resume_clients

.PHONY: server fuzz-request
server: $(BTFD_BIN)
build: $(BTFD_BIN) $(FUZZ_REPLAY) $(RESUME_BIN)

$(SERVER_OBJ): INC := $(call codec_inc,common) -Iserver
$(SERVER_OBJ): PKG_CFLAGS = $(SERVER_CFLAGS)

$(BTFD_BIN): $(SERVER_OBJ) $(CODEC_LIB)
	$(CC) $(LDFLAGS) -o $@ $^ $(SERVER_LIBS) -lm

$(FUZZ_REPLAY): $(FUZZ_SRC) fuzz/replay_main.c server/btfd_request.h
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MF /dev/null -Iserver $(SERVER_CFLAGS) -o $@ $(FUZZ_SRC) fuzz/replay_main.c \
	    $(LDFLAGS) $(FUZZ_LIBS) -lm

$(RESUME_BIN): tests/deploy/resume_clients.c tests/lws_connect.h $(CODEC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MF /dev/null -D_GNU_SOURCE $(CODEC_INNER) -Itests $(SERVER_CFLAGS) -o $@ $< $(CODEC_LIB) \
	    $(LDFLAGS) $(SERVER_LIBS) -lm

# libFuzzer + ASan/UBSan (FUZZ_BUILD, FUZZ_SAN: fuzz/build.mk); `make fuzz` runs it.
fuzz-request:
	@mkdir -p $(FUZZ_BUILD)/fuzz
	clang -std=c11 -g -O1 -D_DEFAULT_SOURCE -fsanitize=fuzzer,$(FUZZ_SAN) -fno-sanitize-recover=undefined -Iserver \
	    $(SERVER_CFLAGS) -o $(FUZZ_BUILD)/fuzz/fuzz_request $(FUZZ_SRC) $(FUZZ_LIBS) -lm

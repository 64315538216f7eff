/* fuzz_request.c - libFuzzer target for the btfd request parser (server/btfd_request.c).
 *
 * Build and run: `make fuzz` (clang -fsanitize=fuzzer,address,undefined).
 * The same target is linked with replay_main.c by `make build` so `make test`
 * re-runs every saved input in fuzz/corpus/request without libFuzzer.
 * Besides memory errors (caught by the sanitizers) it aborts when a result
 * breaks the parser's contract: an accepted request must hold a valid name
 * where its type needs one, in-range chunk indices and budgets; a refused one
 * must carry a non-empty reason.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "btfd_request.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_ok(const btfd_request *rq)
{
    int named = rq->type == BTFD_REQ_SUBSCRIBE || rq->type == BTFD_REQ_BUDGET ||
                rq->type == BTFD_REQ_UNSUBSCRIBE;
    if (rq->type < BTFD_REQ_LIST || rq->type > BTFD_REQ_PING)
        abort();
    if (named != btfd_name_valid(rq->material, strlen(rq->material)) && (named || rq->material[0]))
        abort();
    if (rq->n_have < 0 || rq->n_have > BTFD_HAVE_MAX)
        abort();
    for (int i = 0; i < rq->n_have; i++)
        if (rq->have[i] >= BTFD_CHUNK_MAX)
            abort();
    if (rq->budget.max_chunks < -1 || rq->budget.max_chunks > BTFD_CHUNK_MAX ||
        rq->budget.max_bytes < -1 || isnan(rq->budget.max_error))
        abort();
    if (strlen(rq->etag) > BTFD_ETAG_MAX)
        abort();
    if (rq->budget.pixels != -1.0 && !(rq->budget.pixels >= 0 && rq->budget.pixels <= 1e9))
        abort();
    if (rq->type == BTFD_REQ_ACK && (rq->received < 0 || rq->window < -1 || rq->window > BTFD_WINDOW_MAX ||
                                     (rq->window > 0 && rq->window < BTFD_WINDOW_MIN)))
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    btfd_request rq;
    char why[200];
    memset(why, 'x', sizeof why);
    btfd_req_status s = btfd_request_parse((const char *)data, size, &rq, why, sizeof why);
    if (s == BTFD_REQ_OK)
        check_ok(&rq);
    else if (!memchr(why, 0, sizeof why) || why[0] == 0 || !strcmp(btfd_req_status_code(s), "unknown"))
        abort();
    return 0;
}

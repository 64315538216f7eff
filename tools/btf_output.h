/* btf_output.h - what the `btf` commands show besides their text: a progress line
 * on stderr while long work runs (only when stderr is a terminal), and the one
 * JSON object that --json prints on stdout.
 *
 *     btf_progress pr;
 *     btf_progress_start(&pr, "compress", "blocks");
 *     pca.progress = btf_progress_update, pca.progress_ctx = &pr;
 *     ... work ...
 *     btf_progress_end(&pr);
 */
#ifndef BTF_OUTPUT_H
#define BTF_OUTPUT_H

#include "btf_package.h"

#include <cjson/cJSON.h>
#include <stddef.h>

/* A progress line; stack value of the command doing the work, lives until btf_progress_end. */
typedef struct btf_progress {
    const char *what, *unit; /* "compress", "blocks": static strings */
    int on;                  /* stderr is a terminal: draw */
    int width;               /* characters of the line on screen (0: none) */
    double t0, last;         /* start and last redraw (monotonic seconds) */
} btf_progress;

void btf_progress_start(btf_progress *p, const char *what, const char *unit);
/* done of total units finished; redraws at most 10 times a second (and at the end).
 * The signature of btf_pca_options.progress: ctx is the btf_progress. */
void btf_progress_update(void *ctx, int done, int total);
/* Clears the line. */
void btf_progress_end(btf_progress *p);
/* The line's text: "btf WHAT: DONE/TOTAL UNIT, E s elapsed, about R s left". */
void btf_progress_format(char *buf, size_t n, const char *what, const char *unit, int done, int total,
                         double elapsed);


/* Which per-chunk values p's manifest records (the reports print "-" or null for the
 * others): rmse_float, not in version 4; lab and delta_e76, not with levels. */
void btf_output_recorded(const btf_package *p, int *rmse_float, int *lab);
/* {"path": dir, "bytes", "chunks", "chunk": [{index, component, level, bytes,
 * cumulative, rmse, rmse_float, lab, psnr, delta_e76}]} of the package dir as
 * its manifest records it; NULL (message printed for cmd) when it cannot be read. */
cJSON *btf_json_package(const char *cmd, const char *dir);
/* Prints o on stdout on one line and deletes it; 0 ok, 1 failure. */
int btf_json_print(cJSON *o);

#endif

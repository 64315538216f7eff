/* btf_output.c - progress line and --json output of the `btf` commands (btf_output.h). */
#include "btf_output.h"

#include "btf_common.h"

#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

void btf_progress_start(btf_progress *p, const char *what, const char *unit)
{
    memset(p, 0, sizeof *p);
    p->what = what, p->unit = unit;
    p->on = isatty(STDERR_FILENO);
    p->t0 = p->last = btf_seconds();
}

void btf_progress_format(char *buf, size_t n, const char *what, const char *unit, int done, int total,
                         double elapsed)
{
    int len = snprintf(buf, n, "btf %s: %d/%d %s, %.1f s elapsed", what, done, total, unit, elapsed);
    if (done > 0 && done < total && len > 0 && (size_t)len < n)
        snprintf(buf + len, n - (size_t)len, ", about %.1f s left", elapsed * (total - done) / done);
}

void btf_progress_update(void *ctx, int done, int total)
{
    btf_progress *p = ctx;
    double t = btf_seconds();
    if (!p->on || (done < total && t - p->last < 0.1))
        return;
    char line[160];
    btf_progress_format(line, sizeof line, p->what, p->unit, done, total, t - p->t0);
    int w = (int)strlen(line);
    fprintf(stderr, "\r%s%*s", line, p->width > w ? p->width - w : 0, "");
    fflush(stderr);
    p->width = w > p->width ? w : p->width;
    p->last = t;
}

void btf_progress_end(btf_progress *p)
{
    if (p->on && p->width > 0)
        fprintf(stderr, "\r%*s\r", p->width, "");
    p->width = 0;
}

void btf_output_recorded(const btf_package *p, int *rmse_float, int *lab)
{
    *rmse_float = p->version != 4, *lab = !btf_package_has_levels(p);
}

/* One chunk's entry; cumulative = bytes of chunks 0..i; null or absent where the
 * manifest records no value (btf_output_recorded). */
static cJSON *btf__json_chunk(const btf_package *p, int i, long long cumulative)
{
    int has_float, has_lab;
    btf_output_recorded(p, &has_float, &has_lab);
    const btf_chunk_info *c = &p->chunk[i];
    cJSON *j = cJSON_CreateObject();
    cJSON_AddNumberToObject(j, "index", i);
    cJSON_AddNumberToObject(j, "component", c->component);
    cJSON_AddNumberToObject(j, "level", c->level);
    cJSON_AddNumberToObject(j, "bytes", (double)c->bytes);
    cJSON_AddNumberToObject(j, "cumulative", (double)cumulative);
    cJSON_AddNumberToObject(j, "rmse", c->rmse);
    if (has_float)
        cJSON_AddNumberToObject(j, "rmse_float", c->rmse_float);
    cJSON_AddItemToObject(j, "lab", has_lab ? cJSON_CreateNumber(c->lab) : cJSON_CreateNull());
    cJSON_AddNumberToObject(j, "psnr", c->psnr);
    cJSON_AddItemToObject(j, "delta_e76", has_lab ? cJSON_CreateNumber(c->delta_e76) : cJSON_CreateNull());
    return j;
}

cJSON *btf_json_package(const char *cmd, const char *dir)
{
    btf_package *p = NULL;
    btf_error err = {{0}};
    if (btf_package_read(dir, 1, &p, &err) != BTF_OK) {
        fprintf(stderr, "btf %s: cannot re-read %s: %s\n", cmd, dir, err.msg);
        return NULL;
    }
    cJSON *o = cJSON_CreateObject(), *list = cJSON_CreateArray();
    long long total = 0;
    for (int i = 0; i < p->n_chunks; i++) {
        total += p->chunk[i].bytes;
        cJSON_AddItemToArray(list, btf__json_chunk(p, i, total));
    }
    cJSON_AddStringToObject(o, "path", dir);
    cJSON_AddNumberToObject(o, "bytes", (double)total);
    cJSON_AddNumberToObject(o, "chunks", p->n_chunks);
    cJSON_AddItemToObject(o, "chunk", list);
    btf_package_free(p);
    return o;
}

int btf_json_print(cJSON *o)
{
    char *s = o ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    if (!s) {
        fprintf(stderr, "btf: cannot format the JSON output\n");
        return 1;
    }
    printf("%s\n", s);
    cJSON_free(s);
    return 0;
}

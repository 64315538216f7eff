/* btf_lod_select.c - the reader's side of spatial levels (doc/package-format.md
 * section 10): the scene-driven chunk selection, which prefix of the manifest's
 * chunks a view needs, and the texel look-up between levels the decoders share
 * (btf_lod_texel_of). Uses only manifest fields (no chunk data), so a server can
 * link it without the image or compression code. client/btf-lod.js is its browser twin. */
#include <string.h>

#include "btf_lod.h"

int btf_lod_texel_of(int x, int level, int from)
{
    if (from >= level)
        return x >> (from - level);
    int d = level - from;
    return (x << d) + (1 << (d - 1));
}

double btf_lod_footprint(int width, double repeat, double pixels)
{
    if (!(pixels > 0.0) || width <= 0 || !(repeat > 0.0))
        return 0.0;
    return (double)width * repeat / pixels;
}

/* contrib of component c's chunk at level l (0 when the manifest has none). */
static double btf__contrib(const btf_package *p, int c, int l)
{
    for (int i = 0; i < p->n_chunks; i++)
        if (p->chunk[i].component == c && p->chunk[i].level == l)
            return p->chunk[i].contrib;
    return 0.0;
}

void btf_lod_select(const btf_package *p, const btf_lod_view *view, btf_lod_selection *out, unsigned char *need)
{
    memset(out, 0, sizeof *out);
    double tpp = view ? view->texels_per_pixel : 1.0, thr = view ? view->threshold : BTF_LOD_THRESHOLD;
    if (need)
        memset(need, 0, (size_t)p->n_chunks);
    if (!(tpp > 0.0)) /* off screen (or NaN): nothing */
        return;
    int lev = 0;
    while (lev + 1 < p->n_levels && tpp >= (double)(1 << (lev + 1)))
        lev++;
    out->level = btf_package_has_levels(p) ? lev : 0;
    int c0 = p->chunk[0].component;
    for (int i = 0; i < p->n_chunks; i++) {
        const btf_chunk_info *ci = &p->chunk[i];
        int first = 1; /* first chunk of its component: count the component once */
        for (int e = 0; e < i && first; e++)
            first = p->chunk[e].component != ci->component;
        int vis = !btf_package_has_levels(p) || ci->component == c0 || btf__contrib(p, ci->component, out->level) >= thr;
        if (vis && first)
            out->n_components++;
        if (vis && ci->level >= out->level) {
            out->n_needed++;
            out->limit = i + 1;
            if (need)
                need[i] = 1;
        }
    }
    for (int i = 0; i < out->limit; i++)
        out->bytes += p->chunk[i].bytes;
}

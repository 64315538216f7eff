/* test_source.c - room tools, suite "source": input names of the tools
 * (tools/btf_source.h): generated materials and errors. */
#include <criterion/criterion.h>
#include <stdlib.h>
#include <string.h>

#include "btf_gen.h"
#include "btf_source.h"

Test(source, gen_spec_equals_generator)
{
    btf_ring rings[2] = {{0, 1, 0}, {45, 6, 0}};
    btf_dirset d;
    cr_assert_eq(btf_dirset_make(rings, 2, &d, NULL), BTF_OK);
    btf_load_options o = {.sampling = &d};
    btf *a = NULL, *b = NULL;
    btf_error e = {0};
    cr_assert_eq(btf_source_load("gen:tiles:8:7", &o, &a, &e), BTF_OK, "%s", e.msg);
    btf_gen_params p = btf_gen_defaults(BTF_GEN_TILES);
    p.seed = 7;
    cr_assert_eq(btf_gen_create(&p, 8, 8, &d, &d, BTF_U8, &b, NULL), BTF_OK);
    cr_expect_eq(a->width, 8);
    cr_expect_eq(a->views.n_dirs, 7);
    cr_expect_eq(memcmp(a->data, b->data, a->count), 0);
    btf_free(a);
    btf_free(b);
}

Test(source, bad_specs_are_refused)
{
    static const char *bad[] = {"gen:", "gen:wood", "gen:knit:0", "gen:knit:x", "gen:knit:8:", "gen:knit:8:1:2",
                                "gen:knit:99999"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        btf *m = (btf *)1;
        btf_error e = {0};
        cr_expect_eq(btf_source_load(bad[i], NULL, &m, &e), BTF_ERR_ARG, "%s", bad[i]);
        cr_expect_null(m);
        cr_expect(strstr(e.msg, bad[i]) != NULL, "message names the spec: %s", e.msg);
    }
    btf *m = NULL;
    cr_expect_neq(btf_source_load("/nonexistent/path", NULL, &m, NULL), BTF_OK);
}

/* btf_source_open: views where the input can be read view by view, the BTF loaded whole
 * (and its views a wrap of it) where the caller asks or the input needs it; both give
 * the same samples; a bad name fails with nothing to release. */
Test(source, open_reads_views_where_it_can_and_whole_where_asked)
{
    btf_source_args a = {0};
    btf_source_input v, w, d, bad;
    btf_error e = {0};
    cr_assert_eq(btf_source_open("test", "gen:tiles:8:7", &a, 0, &v, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_source_open("test", "gen:tiles:8:7", &a, 1, &w, &e), BTF_OK, "%s", e.msg);
    cr_expect_null(v.whole, "a generated material is read view by view");
    cr_assert_not_null(w.whole, "asked whole");
    cr_assert_eq(w.views.width, 8);
    size_t n = btf_views_floats(&v.views);
    cr_assert_eq(n, btf_views_floats(&w.views));
    float *x = malloc(n * sizeof(float)), *y = malloc(n * sizeof(float));
    cr_assert(x && y);
    for (int view = 0; view < v.views.views.n_dirs; view += 20) {
        cr_assert_eq(btf_views_fill(&v.views, view, x, &e), BTF_OK, "%s", e.msg);
        cr_assert_eq(btf_views_fill(&w.views, view, y, &e), BTF_OK, "%s", e.msg);
        cr_expect_eq(memcmp(x, y, n * sizeof(float)), 0, "view %d", view);
    }
    free(x), free(y);
    btf_source_close(&v), btf_source_close(&w);
    cr_expect_null(w.whole);
    a.downsample = 2; /* a generated material is made whole to be downsampled */
    cr_assert_eq(btf_source_open("test", "gen:tiles:8:7", &a, 0, &d, &e), BTF_OK, "%s", e.msg);
    cr_assert_not_null(d.whole);
    cr_expect_eq(d.views.width, 4);
    btf_source_close(&d);
    cr_expect_eq(btf_source_open("test", "gen:wood", &a, 0, &bad, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "gen:wood") != NULL, "%s", e.msg);
    cr_expect_null(bad.whole);
    btf_source_close(&bad);
}

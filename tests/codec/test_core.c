/* test_core.c - room codec, suites "core" and "dirset": the BTF container
 * (codec/include/btf.h), its large buffers (btf_common.h) and direction-set basics. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "btf.h"
#include "btf_common.h"

Test(core, result_strings_are_distinct)
{
    for (int a = BTF_OK; a <= BTF_ERR_MISSING; a++)
        for (int b = a + 1; b <= BTF_ERR_MISSING; b++)
            cr_expect_str_neq(btf_result_string(a), btf_result_string(b));
}

Test(core, create_get_set_u8_and_f32)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf *m = NULL;
    cr_assert_eq(btf_create(4, 3, &d, &d, BTF_U8, &m, NULL), BTF_OK);
    cr_assert_eq(m->count, (size_t)4 * 3 * 3 * 81 * 81);
    btf_set(m, 80, 5, 3, 2, 1, 0.5f);
    cr_expect_float_eq(btf_get(m, 80, 5, 3, 2, 1), 128.0f / 255.0f, 1e-6);
    btf_set(m, 0, 0, 0, 0, 0, 7.0f); /* clamps */
    cr_expect_eq(((uint8_t *)m->data)[0], 255);
    btf_set(m, 0, 0, 0, 0, 0, NAN);
    cr_expect_eq(((uint8_t *)m->data)[0], 0);
    btf_free(m);
    cr_assert_eq(btf_create(2, 2, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    btf_set(m, 1, 2, 1, 1, 2, -0.25f);
    cr_expect_eq(btf_get(m, 1, 2, 1, 1, 2), -0.25f);
    cr_expect_eq(btf_check_finite(m, NULL), BTF_OK);
    btf_set(m, 3, 4, 0, 1, 0, INFINITY);
    btf_error e = {0};
    cr_expect_eq(btf_check_finite(m, &e), BTF_ERR_NUMERIC);
    cr_expect(strstr(e.msg, "view 3 light 4") != NULL, "%s", e.msg);
    btf_free(m);
    btf_free(NULL);
}

Test(core, create_rejects_absurd_sizes)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf *m = (btf *)1;
    btf_error e = {0};
    cr_expect_eq(btf_create(0, 4, &d, &d, BTF_U8, &m, &e), BTF_ERR_RANGE);
    cr_expect_null(m);
    cr_expect_eq(btf_create(16384, 16384, &d, &d, BTF_U8, &m, &e), BTF_ERR_RANGE);
    cr_expect(strlen(e.msg) > 0);
}

Test(core, downsample_box_filter)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf *m = NULL, *s = NULL;
    cr_assert_eq(btf_create(4, 4, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 4; x++)
            btf_set(m, 7, 9, x, y, 1, (float)(x + 4 * y));
    cr_assert_eq(btf_downsample(m, 2, &s, NULL), BTF_OK);
    cr_expect_eq(s->width, 2);
    cr_expect_float_eq(btf_get(s, 7, 9, 0, 0, 1), (0 + 1 + 4 + 5) / 4.0f, 1e-6);
    cr_expect_float_eq(btf_get(s, 7, 9, 1, 1, 1), (10 + 11 + 14 + 15) / 4.0f, 1e-6);
    cr_expect_eq(btf_downsample(m, 3, &s, NULL), BTF_ERR_ARG);
    btf_free(m);
    btf_free(s);
}

/* Every sample of the window equals the source's at the shifted texel (btf_get on
 * both: an independent read of the layout), in both storages; windows that leave
 * the material are refused. */
Test(core, crop_copies_the_window)
{
    btf_dirset d = btf_dirset_ubo2003();
    for (int st = BTF_U8; st <= BTF_F32; st++) {
        btf *m = NULL, *c = NULL;
        cr_assert_eq(btf_create(7, 5, &d, &d, (btf_storage)st, &m, NULL), BTF_OK);
        for (int v = 0; v < 81; v += 40)
            for (int l = 0; l < 81; l += 20)
                for (int y = 0; y < 5; y++)
                    for (int x = 0; x < 7; x++)
                        for (int ch = 0; ch < 3; ch++)
                            btf_set(m, v, l, x, y, ch, (float)((v + 3 * l + 5 * x + 11 * y + 17 * ch) % 256) / 255.0f);
        cr_assert_eq(btf_crop(m, 2, 1, 4, 3, &c, NULL), BTF_OK);
        cr_assert(c->width == 4 && c->height == 3 && c->storage == m->storage);
        for (int v = 0; v < 81; v += 40)
            for (int l = 0; l < 81; l += 20)
                for (int y = 0; y < 3; y++)
                    for (int x = 0; x < 4; x++)
                        for (int ch = 0; ch < 3; ch++)
                            cr_assert_eq(btf_get(c, v, l, x, y, ch), btf_get(m, v, l, x + 2, y + 1, ch));
        btf_free(c);
        c = NULL;
        btf_error err = {0};
        cr_expect_eq(btf_crop(m, 4, 0, 4, 3, &c, &err), BTF_ERR_ARG, "one column past the right edge");
        cr_expect_eq(btf_crop(m, 0, 3, 1, 3, &c, &err), BTF_ERR_ARG, "one row past the bottom edge");
        cr_expect_eq(btf_crop(m, -1, 0, 1, 1, &c, &err), BTF_ERR_ARG);
        cr_expect_eq(btf_crop(m, 0, 0, 0, 1, &c, &err), BTF_ERR_ARG);
        cr_expect_null(c);
        btf_free(m);
    }
}

Test(dirset, builtins_have_expected_counts_and_order)
{
    btf_dirset u = btf_dirset_ubo2003(), dome = btf_dirset_dome151();
    cr_expect_eq(u.n_dirs, 81);
    cr_expect_eq(dome.n_dirs, 151);
    float t, p;
    btf_dirset_angles(&u, 0, &t, &p);
    cr_expect(t == 0 && p == 0);
    btf_dirset_angles(&u, 6, &t, &p); /* last of theta 15 ring */
    cr_expect(t == 15 && fabsf(p - 300) < 1e-4f);
    btf_dirset_angles(&u, 57, &t, &p);
    cr_expect(t == 75 && p == 0);
    btf_dirset_angles(&dome, 1, &t, &p);
    cr_expect(t == 11 && fabsf(p - 15) < 1e-4f);
    cr_expect_eq(btf_dirset_find(&u, 45, 20, 0.01f), 19 + 1);
    cr_expect_eq(btf_dirset_find(&u, 45, 21, 0.01f), -1);
    cr_expect_eq(btf_dirset_find(&u, 0, 123, 0.01f), 0);
}

Test(dirset, make_rejects_bad_tables)
{
    btf_dirset d;
    btf_ring bad_order[2] = {{30, 6, 0}, {15, 6, 0}};
    btf_ring bad_pole[1] = {{0, 3, 0}};
    btf_ring bad_theta[1] = {{95, 3, 0}};
    btf_ring bad_count[1] = {{10, 0, 0}};
    cr_expect_eq(btf_dirset_make(bad_order, 2, &d, NULL), BTF_ERR_FORMAT);
    cr_expect_eq(btf_dirset_make(bad_pole, 1, &d, NULL), BTF_ERR_FORMAT);
    cr_expect_eq(btf_dirset_make(bad_theta, 1, &d, NULL), BTF_ERR_RANGE);
    cr_expect_eq(btf_dirset_make(bad_count, 1, &d, NULL), BTF_ERR_RANGE);
    cr_expect_eq(btf_dirset_make(bad_count, 0, &d, NULL), BTF_ERR_RANGE);
}

/* Large buffers (btf_big_alloc, btf_big_calloc): from 8 MiB up aligned to the 2 MiB
 * huge page; zeroed by the calloc form, every byte; an overflowing count refused,
 * not wrapped into a small buffer; small sizes (0 included) are plain buffers. */
Test(core, big_buffers_are_aligned_zeroed_and_bounded)
{
    size_t n = (size_t)9 << 20;
    unsigned char *p = btf_big_calloc(n, 1);
    cr_assert_not_null(p);
    cr_expect_eq((uintptr_t)p % ((uintptr_t)2 << 20), 0, "a 9 MiB buffer on a 2 MiB boundary");
    size_t nonzero = 0;
    for (size_t i = 0; i < n; i++)
        nonzero += p[i] != 0;
    cr_expect_eq(nonzero, 0, "%zu bytes not zeroed", nonzero);
    p[n - 1] = 1; /* the whole buffer is writable */
    free(p);
    cr_expect_null(btf_big_calloc(SIZE_MAX / 4 + 2, 4), "(SIZE_MAX / 4 + 2) x 4 wraps to 4 bytes");
    void *small = btf_big_alloc(0), *one = btf_big_calloc(3, 5);
    cr_expect_not_null(small);
    cr_expect(one && !memcmp(one, "\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 15), "15 zero bytes");
    free(small), free(one);
}

/* btf_big_free keeps one buffer of 8 MiB to 1 GiB, the larger of two freed, for the
 * next btf_big_alloc it can hold (a block matrix filled again then takes no fresh
 * pages); a smaller buffer, and one that no kept buffer holds, are new ones. */
Test(core, a_freed_big_buffer_is_taken_again)
{
    size_t n = (size_t)9 << 20;
    void *drain = btf_big_alloc(n); /* whatever an earlier test left kept */
    btf_big_free(drain, 1);
    unsigned char *a = btf_big_alloc(n), *b = btf_big_alloc(2 * n);
    cr_assert(a && b);
    a[n - 1] = 7;
    btf_big_free(a, n);
    btf_big_free(b, 2 * n); /* the larger one is kept, a freed */
    unsigned char *c = btf_big_alloc(n + 1);
    cr_expect_eq(c, b, "a request it holds takes the kept buffer");
    unsigned char *d = btf_big_alloc(n);
    cr_expect_neq(d, b, "nothing kept: a new buffer");
    cr_expect_eq((uintptr_t)d % ((uintptr_t)2 << 20), 0, "a new buffer on a 2 MiB boundary");
    btf_big_free(c, n + 1);
    unsigned char *e = btf_big_alloc(3 * n);
    cr_expect_neq(e, c, "the kept buffer is too small for it");
    cr_expect_eq(btf_big_alloc(n), c, "still kept after a request it could not hold");
    btf_big_free(c, n), btf_big_free(d, n), btf_big_free(e, 3 * n);
    void *small = btf_big_alloc(16);
    btf_big_free(small, 16); /* a plain buffer: freed, not kept */
    cr_expect_eq(btf_big_alloc(n), e, "the 27 MiB one is kept, not the 16 bytes");
    free(e);
}

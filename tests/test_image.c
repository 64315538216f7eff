/* test_image.c - suite "image": the image writer's PNG filter choice
 * (BTF_IMAGE_PNG_SMALLEST, codec/btf_image.h). Checked against the writer's own
 * default encoding of the same pixels and against the pixels themselves. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "test_util.h"

static unsigned lcg(unsigned *s)
{
    *s = *s * 1103515245u + 12345u;
    return *s >> 16;
}

/* One image written both ways: the smallest choice decodes to the same samples, is no
 * larger than the default (adaptive) encoding, and leaves no temporary file. */
static long long check_one(const char *dir, int w, int h, int ch, int bits, const void *px, long long *adaptive)
{
    char a[600], s[600];
    btf_error err = {0};
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(s, sizeof s, "%s/s.png", dir);
    cr_assert_eq(btf_image_write(a, w, h, ch, bits, px, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_image_write_flags(s, w, h, ch, bits, px, BTF_IMAGE_PNG_SMALLEST, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(test_count_files(dir), 2, "temporary files left in %s", dir);
    size_t n = (size_t)w * h * ch;
    if (bits == 8) {
        uint8_t *back = NULL;
        int bw, bh, bc;
        cr_assert_eq(btf_image_read_u8(s, &bw, &bh, &bc, &back, &err), BTF_OK, "%s", err.msg);
        cr_assert(bw == w && bh == h && bc == ch);
        cr_assert_eq(memcmp(back, px, n), 0, "%dx%d: the smallest choice decodes to other samples", w, h);
        free(back);
    }
    *adaptive = btf_fs_size(a);
    long long sz = btf_fs_size(s);
    remove(a);
    remove(s);
    return sz;
}

Test(image, smallest_png_filter_choice)
{
    char dir[256];
    cr_assert(test_tmpdir(dir, sizeof dir));
    unsigned seed = 99;
    /* sizes with the whole image judged (<= 128 rows) and with the middle strip */
    int sizes[3][2] = {{40, 30}, {96, 128}, {300, 260}};
    for (int k = 0; k < 3; k++) {
        int w = sizes[k][0], h = sizes[k][1];
        uint8_t *px = malloc((size_t)w * h);
        /* columns that vary, rows that repeat them with a little noise (Up's case),
         * then noise (None's case) */
        for (int kind = 0; kind < 2; kind++) {
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    px[y * w + x] = (uint8_t)(kind == 0 ? (x * 37 % 200) + lcg(&seed) % 3 : lcg(&seed) & 255);
            long long adaptive, s = check_one(dir, w, h, 1, 8, px, &adaptive);
            cr_assert(s > 0 && s <= adaptive, "%dx%d kind %d: %lld bytes, adaptive %lld", w, h, kind, s, adaptive);
        }
        free(px);
    }
    /* more channels and 16 bits go through the same choice */
    int w = 64, h = 200;
    uint16_t *p16 = malloc((size_t)w * h * 2 * sizeof *p16);
    for (int i = 0; i < w * h * 2; i++)
        p16[i] = (uint16_t)((i % (2 * w)) * 300 + lcg(&seed) % 5);
    long long adaptive, s = check_one(dir, w, h, 2, 16, p16, &adaptive);
    cr_assert(s > 0 && s <= adaptive, "16-bit: %lld bytes, adaptive %lld", s, adaptive);
    free(p16);
    cr_assert_eq(test_rmtree(dir), 0);
}

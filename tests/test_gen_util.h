/* test_gen_util.h - the one generated-material helper of the Criterion tests
 * (header only; the tests link bench/gen). */
#ifndef BTF_TEST_GEN_UTIL_H
#define BTF_TEST_GEN_UTIL_H

#include <criterion/criterion.h>

#include "btf_gen.h"

/* KIND at size x size texels, 8-bit, lights = views = the n rings given (NULL: the
 * pole and 6 directions at 45 degrees); the caller frees it (btf_free). */
static inline btf *test_material(btf_gen_kind kind, int size, const btf_ring *rings, int n)
{
    static const btf_ring dflt[2] = {{0.0f, 1, 0.0f}, {45.0f, 6, 0.0f}};
    btf_dirset d;
    btf_error err = {0};
    cr_assert_eq(btf_dirset_make(rings ? rings : dflt, rings ? n : 2, &d, &err), BTF_OK, "%s", err.msg);
    btf_gen_params gp = btf_gen_defaults(kind);
    btf *b = NULL;
    cr_assert_eq(btf_gen_create(&gp, size, size, &d, &d, BTF_U8, &b, &err), BTF_OK, "%s", err.msg);
    return b;
}

#endif

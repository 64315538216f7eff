/* fuzz_dirset.c - libFuzzer target for the direction-set JSON reader
 * (btf_dirset_parse_json, codec/common/btf_dirset_json.c): ring tables and direction
 * lists. An accepted set must be
 * within the limits and interpolate: finite weights that sum to 1, indices in range.
 * Both ways: the ring walk (a list set's table, btf_dirtab_build_list, behind it) and
 * a ring set's direction table (btf_dirtab_build, codec/common/btf_dirtab.c: the
 * triangles and the 64 x 64 cell walk), which fuzz_roundtrip no longer builds. */
#include <math.h>

#include "btf.h"
#include "btf_dirtab.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* An interpolation of d: finite weights >= 0 that sum to 1, indices in range. */
static void check_interp(const btf_dirset *d, btf_interp it)
{
    double sum = 0.0;
    for (int j = 0; j < 3; j++) {
        FUZZ_CHECK(isfinite(it.w[j]) && it.w[j] >= -1e-6f && it.idx[j] >= 0 && it.idx[j] < d->n_dirs);
        sum += it.w[j];
    }
    FUZZ_CHECK(fabs(sum - 1.0) < 1e-4);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    btf_dirset d;
    btf_error err = {{0}};
    if (btf_dirset_parse_json((const char *)data, size, "fuzz", &d, &err) != BTF_OK) {
        FUZZ_CHECK(err.msg[0] != 0 && !strchr(err.msg, '\n'));
        return 0;
    }
    if (btf_dirset_is_list(&d))
        FUZZ_CHECK(d.n_dirs >= 3 && d.n_dirs <= BTF_MAX_LIST_DIRS);
    else
        FUZZ_CHECK(d.n_rings >= 1 && d.n_rings <= BTF_MAX_RINGS && d.n_dirs >= 1 && d.n_dirs <= BTF_MAX_DIRS);
    static const float probes[][3] = {{0, 0, 1}, {1, 0, 0.2f}, {-0.3f, 0.8f, 0.5f}, {0, 0, -1}, {0.2f, -0.9f, 0.01f}};
    btf_dirtab *t = NULL;
    if (!btf_dirset_is_list(&d))
        FUZZ_CHECK(btf_dirtab_build(&d, &t, &err) == BTF_OK);
    for (size_t i = 0; i < sizeof probes / sizeof probes[0]; i++) {
        check_interp(&d, btf_dirset_interp_vec(&d, probes[i]));
        if (t)
            check_interp(&d, btf_dirtab_interp_vec(t, probes[i]));
    }
    btf_dirtab_free(t);
    return 0;
}

/* fuzz_ubo2003_name.c - libFuzzer target for the UBO2003 file-name parser
 * (btf_ubo2003_name_angles, codec/input/btf_ubo2003.c): accepted names give angles in
 * range, and the canonical name written back from them parses to the same angles. */
#include "btf_io.h"
#include "fuzz_util.h"
#include "btf_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char name[300];
    if (size >= sizeof name)
        size = sizeof name - 1;
    memcpy(name, data, size);
    name[size] = 0;
    int a[4];
    if (!btf_ubo2003_name_angles(name, a))
        return 0;
    FUZZ_CHECK(a[0] >= 0 && a[0] <= 999 && a[1] >= 0 && a[1] <= 999 && a[2] >= 0 && a[2] <= 999 && a[3] >= 0 &&
               a[3] <= 999);
    char again[64];
    int b[4];
    snprintf(again, sizeof again, "x_00000_tl%03d_pl%03d_tv%03d_pv%03d.png", a[0], a[1], a[2], a[3]);
    FUZZ_CHECK(btf_ubo2003_name_angles(again, b) && !memcmp(a, b, sizeof a));
    return 0;
}

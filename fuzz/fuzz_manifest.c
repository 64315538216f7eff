/* fuzz_manifest.c - libFuzzer target for the package manifest parser
 * (btf_manifest_parse, codec/format/btf_manifest.c). An accepted manifest must print
 * back (btf_manifest_print) into one that parses to the same chunk list, and
 * the level selection must stay within it. */
#include "btf_lod.h"
#include "btf_manifest.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_round_trip(const btf_package *a)
{
    btf_error err = {{0}};
    char *text = btf_manifest_print(a, &err);
    FUZZ_CHECK(text != NULL);
    btf_package b;
    memset(&b, 0, sizeof b);
    FUZZ_CHECK(btf_manifest_parse(text, "printed", &b, &err) == BTF_OK);
    FUZZ_CHECK(b.n_chunks == a->n_chunks && b.version == a->version && b.n_levels == a->n_levels);
    for (int i = 0; i < a->n_chunks; i++)
        FUZZ_CHECK(b.chunk[i].component == a->chunk[i].component && b.chunk[i].level == a->chunk[i].level &&
                   b.chunk[i].bytes == a->chunk[i].bytes && b.chunk[i].n_files == a->chunk[i].n_files &&
                   b.chunk[i].has_pred == a->chunk[i].has_pred &&
                   !memcmp(&b.chunk[i].pred, &a->chunk[i].pred, sizeof a->chunk[i].pred));
    btf_manifest_clear(&b);
    free(text);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    btf_package p;
    memset(&p, 0, sizeof p);
    btf_error err = {{0}};
    if (btf_manifest_parse(text, "fuzz", &p, &err) == BTF_OK) {
        FUZZ_CHECK(p.n_chunks >= 1 && p.n_chunks <= BTF_PACKAGE_MAX_CHUNKS && p.blocks && p.n_levels >= 1);
        check_round_trip(&p);
        btf_lod_view v = {4.0, 1.0};
        btf_lod_selection s;
        btf_lod_select(&p, &v, &s, NULL);
        FUZZ_CHECK(s.limit >= 0 && s.limit <= p.n_chunks && s.bytes >= 0);
    } else {
        FUZZ_CHECK(err.msg[0] != 0);
    }
    btf_manifest_clear(&p);
    free(text);
    return 0;
}

/* btf_source.h - the command-line tools' one way to name an input BTF.
 *
 *     btf_source_load("gen:knit:64", &opt, &b, &err);      // generated in memory
 *     btf_source_load("wool/", &opt, &b, &err);            // anything btf_load_any reads
 *
 * "gen:KIND[:SIZE[:SEED]]" generates KIND (knit, tiles, stone) at SIZE x SIZE
 * texels (default 64), seed SEED (default the kind's), sampled at opt->sampling
 * (default UBO2003) for lights and views, without writing any file.
 */
#ifndef BTF_SOURCE_H
#define BTF_SOURCE_H

#include "btf_io.h"

btf_result btf_source_load(const char *spec, const btf_load_options *opt, btf **out, btf_error *err);

#endif

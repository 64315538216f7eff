/* btf_chart.h - `btf chart`: every method setting of the registry (bench/eval/btf_method.h)
 * run on a set of materials, the numbers behind doc/chart-*.csv, and the gnuplot
 * charts drawn from those CSV files.
 *
 *     btf_chart *c;
 *     btf_chart_create(&c, &err);
 *     btf_chart_options o = {0};                       // zero = defaults
 *     btf_chart_add_material(c, "knit", src, &o, &err); // runs every setting on src
 *     btf_chart_finish(c);                             // "mean" rows, Pareto marks
 *     btf_chart_write_csv(c, "doc", &err);             // doc/chart-*.csv
 *     btf_chart_plot("doc", "doc", &err);              // doc/chart-*.{svg,png} (gnuplot)
 *     btf_chart_free(c);
 *
 * Per (material, setting) row: encode wall time, bytes (btf_model_bytes), CIELab
 * error over the whole BTF at the measured directions (btf_metrics lab_thesis of the
 * decoded values against the source), decode cost per fragment (btf_model_cost), and
 * for the PCA settings the shader time per frame of the project's package at the same
 * C (headless GL, `render` program of shaders/, 1280x720 plane filling the frame;
 * measured once per C on a k = 3 package of the first material: the fragment work
 * depends on C, not on k or the material).
 * Streaming rows: the error after each received chunk of the project's package
 * (k 3, C 8, 8 bits; the manifest's numbers, which the writer computes here over
 * every texel, and with verify_stream recomputed over the whole BTF) and after each component file of the thesis-format export of the same
 * source (btf_export.h; files in the format's order 0.png, 1.png, ...; meta.json and
 * R.png, without which nothing decodes, are counted with 0.png).
 *
 * CSV files (plain, no quoting: fields never hold commas; empty = not measured):
 * - chart-speed-accuracy.csv: material, label, family, method, k, components, lobes,
 *   levels, decode_levels, ok, encode_s, decode_s, lab (CIELab thesis MAE), delta_e76,
 *   rmse (0..255), bytes, fetches, flops, cost (= fetches + flops), shader_ms,
 *   pareto_cost, pareto_bytes, n_fallback, n_unconverged, note. Material "mean" rows
 *   average the settings that succeeded on every material.
 * - chart-streaming.csv: material, format (package|thesis|levels: the package with
 *   residual spatial levels, version 4, its error at level 0|float: the float PCA of
 *   the package's k at the package's bytes after the same number of chunks;
 *   package-k1, float-k1, package-kall, float-kall: the same at k = 1 and k = every
 *   view, not in quick runs), step, file (what arrived), bytes (cumulative), lab,
 *   lab_manifest.
 * - chart-compress-time.csv: label, family, then encode seconds per material and mean.
 * Byte counts: "pca", "lpyr", "phong", "lafortune" count float32 parameters;
 * "pca-q" and the streaming rows count the files a client receives.
 *
 * Pareto front: a row is on it when no other row of the same material has both a
 * lower-or-equal x and a lower-or-equal error with one of them strictly lower;
 * x = fetches + flops (pareto_cost) or bytes (pareto_bytes).
 *
 * Limitations: runs in the calling process, temporary packages under $TMPDIR (or
 * /tmp), removed afterwards. Plotting needs `gnuplot` (svg and pngcairo terminals)
 * on PATH. Library-style: nothing printed except through opt->log.
 */
#ifndef BTF_CHART_H
#define BTF_CHART_H

#include <stdio.h>

#include "btf.h"
#include "btf_method.h"

#define BTF_CHART_NAME 64

/* Options; zero means default. Plain value, read during each call. */
typedef struct btf_chart_options {
    int quick;         /* 1: a reduced registry (btf_chart_setting_quick) */
    int shader;        /* 1: time the PCA shader (needs a headless GL); 0: leave shader_ms empty */
    int shader_width;  /* 0 = 1280 */
    int shader_height; /* 0 = 720 */
    int shader_frames; /* timed frames after one warm-up; 0 = 3 */
    int no_stream;     /* 1: skip the streaming rows */
    int no_methods;    /* 1: streaming rows only (e.g. the same material at another size) */
    int verify_stream; /* 1: recompute the package's per-chunk error over the whole BTF
                          (else lab = the manifest's number, written over every texel) */
    int threads;       /* error computation threads; 0 = OpenMP's default (OMP_NUM_THREADS) */
    FILE *log;         /* progress lines, or NULL for silence */
} btf_chart_options;

/* One (material, method setting) result; owned by its btf_chart. */
typedef struct btf_chart_row {
    char material[BTF_CHART_NAME]; /* "mean" for the average over materials */
    char label[48], family[48], method[16];
    int k, components, lobes, levels, decode_levels; /* as resolved by the method */
    int ok;                       /* 0: the method failed on this material (see note) */
    char note[160];               /* error message, or why shader_ms is empty */
    double encode_s;              /* encoder wall time */
    double decode_s;              /* CPU wall time to decode every measured sample */
    double lab, delta_e76, rmse;  /* whole BTF at measured directions */
    double bytes;                 /* btf_model_bytes (mean over materials in "mean" rows) */
    double fetches, flops;        /* per fragment (btf_model_cost) */
    double shader_ms;             /* ms/frame, NAN when not measured */
    int pareto_cost, pareto_bytes;
    int n_fallback, n_unconverged; /* lafortune fits */
} btf_chart_row;

/* One point of a streaming curve; owned by its btf_chart. */
typedef struct btf_chart_stream_row {
    char material[BTF_CHART_NAME];
    char format[16];      /* "package", "thesis", "levels", "float" (the PCA before quantisation), or
                           * "package-k1", "float-k1", "package-kall", "float-kall" */
    int step;             /* 1 = after the first chunk / component file */
    char file[96];        /* what arrived at this step */
    long long bytes;      /* received so far */
    double lab;           /* whole BTF, measured directions (package: = lab_manifest unless verified) */
    double lab_manifest;  /* package: the manifest's number; NAN for the thesis format */
} btf_chart_stream_row;

/* Accumulated results. Made by btf_chart_create, freed by btf_chart_free. */
typedef struct btf_chart {
    btf_chart_row *rows;
    int n_rows, cap_rows;
    btf_chart_stream_row *stream;
    int n_stream, cap_stream;
    int n_materials;
    double shader_ms_by_c[65]; /* cache per C (index = C <= 64); 0 = not yet measured */
    char shader_note[160];
} btf_chart;

btf_result btf_chart_create(btf_chart **out, btf_error *err);
void btf_chart_free(btf_chart *c);

/* 1 when a registry setting belongs to the --quick subset. */
int btf_chart_setting_quick(const btf_method_setting *s);

/* Runs every setting (or the quick subset) on src and the streaming comparison;
 * name labels the rows (letters, digits, '-', '_', '.'; others become '_'). A method
 * that fails on src gives a row with ok = 0 and its message; other failures (memory,
 * temporary files) are returned. */
btf_result btf_chart_add_material(btf_chart *c, const char *name, const btf *src, const btf_chart_options *opt,
                                  btf_error *err);

/* Adds the "mean" rows (settings that succeeded on every material) and marks the
 * Pareto fronts of every material and of the mean. Call once, after the last material. */
btf_result btf_chart_finish(btf_chart *c, btf_error *err);

/* Pareto marking: front[i] = 1 when no j has x[j] <= x[i], y[j] <= y[i] and one of
 * them strictly lower (minimising both); non-finite points are never on the front. */
void btf_chart_pareto(const double *x, const double *y, int n, int *front);

/* Writes DIR/chart-speed-accuracy.csv, chart-streaming.csv, chart-compress-time.csv
 * (temporary name, then rename). */
btf_result btf_chart_write_csv(const btf_chart *c, const char *dir, btf_error *err);

/* Runs gnuplot on csv_dir's CSV files, writing out_dir/chart-*.svg and .png. */
btf_result btf_chart_plot(const char *csv_dir, const char *out_dir, btf_error *err);

#endif

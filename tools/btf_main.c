/* btf_main.c - the `btf` command: dispatches to one tools/cmd_*.c per subcommand. */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_version.h"

#include <cblas.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One row per subcommand; static table, lives for the program. */
typedef struct btf_command {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *help;
} btf_command;

static const btf_command commands[] = {
    /* BTF_COMMANDS: one line per subcommand, keep sorted */
    {"chart", cmd_chart, "every method on MATERIALs: speed/accuracy/streaming CSVs and charts"},
    {"compress", cmd_compress, "k-view PCA of a BTF into a streamable package directory"},
    {"eval", cmd_eval, "error metrics (RGB MAE/RMSE, PSNR, CIELab) of TEST against REF"},
    {"export-thesis", cmd_export_thesis, "k-view PCA written in the thesis's package format (baseline)"},
    {"gen", cmd_gen, "synthetic material (knit, tiles, stone) with known ground truth"},
    {"gen-model", cmd_gen_model, "a small glTF product (a stool of three materials) with known geometry"},
    {"import-thesis", cmd_import_thesis, "reconstruct a thesis package into images or a .btf file"},
    {"library", cmd_library, "build a library (one package per source, parallel jobs, up-to-date skipping); publish it for a static host"},
    {"lod", cmd_lod, "add spatial levels (package version 2) to a compressed package"},
    {"render", cmd_render, "render a package on a plane, sphere, cylinder or glTF model to PNG (headless GL)"},
    {NULL, NULL, NULL},
};

static void usage(FILE *f)
{
    fprintf(f, "usage: btf COMMAND [ARGS...]\n       btf --version | --help\n\ncommands:\n");
    for (const btf_command *c = commands; c->name; c++)
        fprintf(f, "  %-14s %s\n", c->name, c->help);
    fprintf(f, "\n`btf COMMAND --help` describes one command.\n");
    btf_args_exit_codes(f);
}

int main(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("btf %s\n", BTF_VERSION);
        return 0;
    }
    /* One thread pool: the codec shares its work out on OpenMP's threads; OpenBLAS's
     * own pool beside them (a thread per core, waiting by yielding) took 1.15-1.2x
     * the wall time of a compress beside one busy process and 3.6-4.7x beside
     * low-priority ones, and won 7% only on an idle machine at 256x256
     * (doc/performance.md section 4, "BLAS threads"). OPENBLAS_NUM_THREADS, when
     * set, decides instead. */
    if (!getenv("OPENBLAS_NUM_THREADS"))
        openblas_set_num_threads(1);
    for (const btf_command *c = commands; c->name; c++)
        if (!strcmp(c->name, argv[1]))
            return c->run(argc - 1, argv + 1);
    fprintf(stderr, "btf: unknown command '%s'\n", argv[1]);
    usage(stderr);
    return 2;
}

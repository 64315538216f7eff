/* cmd_library.c - `btf library build SRC... --out LIB [-j N]`: a library of packages,
 * one independent job per material (tools/btf_cli.h); `btf library publish LIB OUT`: the
 * library as files for a static host (btfd's --publish mode, library_publish below).
 *
 *     btf library build wool/ corduroy.btf gen:knit:64 --out lib -j 4
 *     btf library build stone=/data/stone --out lib --components 12
 *
 * Every SRC becomes the package LIB/NAME (NAME: the part before "=" in
 * NAME=SRC, else SRC's last path element without its extension, or for
 * gen:KIND:SIZE the spec with ':' as '-'). Each job runs in its own process
 * (at most N at once) and writes through btf_package_compress, which builds
 * LIB/NAME.tmp-PID and renames it into place: a failed job leaves nothing
 * behind and the other jobs go on. A package is up to date, and skipped, when
 * LIB/.build/NAME.json (written atomically after the package, hidden from
 * btfd) records the same source, source mtime and size (for a directory: the
 * newest mtime and the total size below it), settings and btf version, and the
 * package's manifest is still the one that build wrote. So any job runner
 * (make -j, xargs -P, GNU parallel, one machine per job on a shared LIB) can
 * run one `btf library build SRC --out LIB` per material.
 * The parent process only stats files and forks: it must not run OpenMP code
 * before a fork (libgomp's threads do not survive into the child, whose next
 * parallel region would hang), so callers in-process (tests) keep OpenMP out
 * of their own process too.
 */
#define _XOPEN_SOURCE 700
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_fs.h"
#include "btf_lod.h"
#include "btf_lossy.h"
#include "btf_output.h"
#include "btf_package.h"
#include "btf_source.h"
#include "btf_version.h"
#include "btf_common.h"

#include <errno.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define LIB_JOBS_MAX 256

/* Parsed command line; stack value of cmd_library, strings point into argv. */
typedef struct library_opts {
    const char *out;
    const char **src; /* n_src sources (malloc'd array of argv pointers) */
    int n_src;
    btf_pca_options pca;
    btf_package_options pkg;
    const char *sampling; /* --sampling S for image-directory sources; NULL: inferred */
    int downsample, levels, jobs, force, quiet;
    int plain;         /* --plain: equal-noise steps (version 1, or 2 with levels), not rate-distortion */
    int lossless;      /* --lossless: rate-distortion steps without lossy WebP textures */
    int avif;          /* --avif: lossy textures as AVIF, as `btf compress --avif` */
    btf_budget budget; /* --max-bytes / --max-error per material; both 0 = none */
} library_opts;

/* One material to build; array owned by cmd_library, lives for the command. */
typedef struct library_job {
    const char *spec;                  /* the SRC part */
    char name[BTF_PACKAGE_NAME_MAX];   /* package name in LIB */
    pid_t pid;                         /* running child, 0 when not started or done */
    double t0;
} library_job;

static void library_usage(FILE *f)
{
    fprintf(f,
            "usage: btf library build SRC... --out LIB [-j N] [--k K] [--components C] [--bits 8|16]\n"
            "                         [--method M] [--downsample F] [--levels N] [--sampling S]\n"
            "                         [--max-bytes N | --max-error E] [--plain] [--lossless] [--avif] [--linear]\n"
            "                         [--force] [--quiet]\n"
            "\n"
            "Builds one package per SRC into the library directory LIB (what btfd serves), one job\n"
            "per material, at most N at once (default 1). SRC is anything `btf compress` reads\n"
            "(a UBO2003 image directory, a thesis package, a .btf file, gen:KIND[:SIZE[:SEED]]),\n"
            "optionally as NAME=SRC; else NAME is SRC's last path element without extension\n"
            "(gen:knit:64 -> gen-knit-64). Each package is written atomically, with its\n"
            "thumbnail.png (as `btf compress` writes it); a failed job\n"
            "leaves nothing behind and the others go on. A package whose source (path, mtime,\n"
            "size), settings and btf version are those of its last build (LIB/.build/NAME.json)\n"
            "is skipped, so make -j or xargs -P can run one `btf library build SRC --out LIB`\n"
            "per material.\n"
            "  --out LIB        library directory (created if missing)\n"
            "  -j, --jobs N     jobs at once, 1..256 (default 1)\n"
            "  --k, --components, --bits, --method, --downsample, --levels, --sampling\n"
            "                   as for `btf compress` (the sampling of every directory SRC)\n"
            "  --max-bytes N, --max-error E\n"
            "                   each material's budget, as for `btf compress` (k and the chunk\n"
            "                   count chosen by measuring; --k, --components fix them)\n"
            "  --plain          equal-noise steps (version 1, 2 with --levels) instead of the\n"
            "                   default rate-distortion steps (version 3, 4 with --levels)\n"
            "  --lossless       lossless textures only, as `btf compress --lossless` (default:\n"
            "                   a lossy WebP texture where it wins, as `btf compress`)\n"
            "  --avif           lossy textures as AVIF, as `btf compress --avif`\n"
            "  --linear         packages of linear light, as `btf compress --linear` (for\n"
            "                   environment light: doc/lighting.md)\n"
            "  --force          rebuild even when up to date\n"
            "  --quiet          print only failures\n"
            "\n"
            "usage: btf library publish LIB OUT [--client DIR]\n"
            "\n"
            "Writes the library LIB into the folder OUT for any static HTTP server or CDN, at the\n"
            "paths btfd serves: OUT/materials.json (the list), OUT/materials/NAME/thumbnail.png,\n"
            "OUT/materials/NAME/ETAG/FILE (immutable), and the viewer's scripts (*.js of --client DIR,\n"
            "by default the bundle beside this program). Files are written atomically and only when\n"
            "they change; nothing is removed, so the packages an older list names stay. It runs\n"
            "`btfd --library LIB --publish OUT`, the btfd beside this program (or $BTFD).\n");
    btf_args_exit_codes(f);
}

static const btf_args_spec library_spec = {
    "library build", "out:o jobs:j j:j k:k components:C method:m downsample:d bits:b levels:l sampling:S linear!L "
    "max-bytes:B max-error:E plain!A lossless!O avif!V force!f quiet!q",
    library_usage, -1};

/* One option or positional of `btf library build` (btf_args_fn). */
static int library_option(void *ctx, const btf_args *a, int c, const char *v)
{
    library_opts *o = ctx;
    btf_args_pca_dst pca = {&o->pca.k, &o->pca.components, &o->downsample, &o->pca.method, BTF_PACKAGE_MAX_CHUNKS,
                            &o->budget};
    switch (c) {
    case BTF_ARG_POS: o->src[o->n_src++] = v; return 0;
    case 'o': o->out = v; return 0;
    case 'j': return btf_args_int(a, v, 1, LIB_JOBS_MAX, &o->jobs);
    case 'b': return btf_arg_int(v, 8, 16, &o->pkg.bits) && o->pkg.bits % 8 == 0 ? 0 : btf_args_bad(a, v, "8 or 16");
    case 'l': return btf_args_int(a, v, 1, BTF_LOD_MAX_LEVELS, &o->levels);
    case 'S': o->sampling = v; return 0;
    case 'L': o->pkg.linear = 1; return 0;
    case 'A': o->plain = 1; return 0;
    case 'O': o->lossless = 1; return 0;
    case 'V': o->avif = 1; return 0;
    case 'B': return btf_args_long(a, v, 1, (long)1 << 40, &o->budget.max_bytes);
    case 'E': return btf_args_double(a, v, 1e-6, 1e6, &o->budget.max_error);
    case 'f': o->force = 1; return 0;
    case 'q': o->quiet = 1; return 0;
    default: return btf_args_pca(a, c, v, &pca);
    }
}

/* NAME of spec ("NAME=SRC", a path, or gen:...) into name; 0, or -1 if it is no valid name. */
static int job_name(const char *spec, char *name, size_t n, const char **src)
{
    const char *eq = strchr(spec, '=');
    *src = eq ? eq + 1 : spec;
    if (eq) {
        snprintf(name, n, "%.*s", (int)(eq - spec), spec);
    } else {
        size_t len = strlen(spec);
        while (len > 1 && spec[len - 1] == '/')
            len--;
        const char *b = spec + len;
        while (b > spec && b[-1] != '/')
            b--;
        snprintf(name, n, "%.*s", (int)(spec + len - b), b);
        char *dot = strrchr(name, '.');
        if (dot && dot != name && strncmp(spec, "gen:", 4))
            *dot = 0;
        for (char *p = name; *p; p++)
            *p = *p == ':' ? '-' : *p;
    }
    if (!name[0] || name[0] == '.' || strlen(name) >= n - 1)
        return -1;
    for (const char *p = name; *p; p++)
        if (!strchr("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-", *p))
            return -1;
    return strstr(name, ".tmp-") || strstr(name, ".old-") ? -1 : 0;
}

/* Newest mtime and total size of the regular files below a directory (nftw; one walk at a time). */
static long long walk_mtime, walk_bytes;
static int walk_one(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)path, (void)ftw;
    long long mt = (long long)st->st_mtim.tv_sec * 1000000000 + st->st_mtim.tv_nsec;
    if (flag == FTW_F || flag == FTW_D || flag == FTW_DP)
        walk_mtime = mt > walk_mtime ? mt : walk_mtime;
    if (flag == FTW_F)
        walk_bytes += (long long)st->st_size;
    return 0;
}

/* What the stamp says about the source: "mtime size"; gen: sources have none. */
static void source_identity(const char *src, char *buf, size_t n)
{
    struct stat st;
    walk_mtime = walk_bytes = 0;
    if (!strncmp(src, "gen:", 4) || stat(src, &st) != 0)
        snprintf(buf, n, "0 0");
    else if (S_ISDIR(st.st_mode) && nftw(src, walk_one, 16, FTW_PHYS) == 0)
        snprintf(buf, n, "%lld %lld", walk_mtime, walk_bytes);
    else
        snprintf(buf, n, "%lld %lld", (long long)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec,
                 (long long)st.st_size);
}

/* The stamp LIB/.build/NAME.json would have now (text into buf); 0, or -1 without a package. */
static int stamp_text(const library_opts *o, const library_job *j, char *buf, size_t n)
{
    char mpath[BTF_FS_PATH_MAX], id[64];
    struct stat st;
    snprintf(mpath, sizeof mpath, "%s/%s/manifest.json", o->out, j->name);
    if (stat(mpath, &st) != 0)
        return -1;
    source_identity(j->spec, id, sizeof id);
    snprintf(buf, n,
             "{\"source\": \"%s\", \"source_mtime_size\": \"%s\", \"btf\": \"%s\",\n"
             " \"settings\": \"k=%d components=%d bits=%d method=%d downsample=%d levels=%d sampling=%s%s rd=%d "
             "lossy=%d max_bytes=%lld max_error=%.17g\",\n"
             " \"thumbnail\": %d,\n"
             " \"manifest_mtime_size\": \"%lld %lld\"}\n",
             j->spec, id, BTF_VERSION, o->pca.k, o->pca.components, o->pkg.bits, (int)o->pca.method, o->downsample,
             o->levels, o->sampling ? o->sampling : "-", o->pkg.linear ? " linear" : "", o->pkg.rd,
             o->pkg.lossy, o->budget.max_bytes, o->budget.max_error, o->pkg.thumbnail,
             (long long)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec, (long long)st.st_size);
    return 0;
}

static void stamp_path(const library_opts *o, const library_job *j, char *buf, size_t n)
{
    snprintf(buf, n, "%s/.build/%s.json", o->out, j->name);
}

/* 1 when LIB/NAME exists and its stamp matches the source and settings as they are now. */
static int up_to_date(const library_opts *o, const library_job *j)
{
    char want[6000], path[BTF_FS_PATH_MAX], *have = NULL;
    stamp_path(o, j, path, sizeof path);
    if (stamp_text(o, j, want, sizeof want) || btf_fs_read(path, sizeof want, &have, NULL, NULL) != BTF_OK)
        return 0;
    int same = !strcmp(have, want);
    free(have);
    return same;
}

/* The child's work: load, compress into LIB/NAME, stamp. Returns the exit code. */
static int build_one(const library_opts *o, const library_job *j)
{
    btf_error err = {0};
    char out[BTF_FS_PATH_MAX], stamp[6000], path[BTF_FS_PATH_MAX];
    snprintf(out, sizeof out, "%s/%s", o->out, j->name);
    btf_package_options pkg = o->pkg;
    pkg.name = j->name;
    btf_source_args sa = {.downsample = o->downsample, .sampling = o->sampling};
    btf_lod_options lod = {0};
    lod.levels = o->levels;
    btf_source_input in;
    btf_budget_result res;
    int budget = o->budget.max_bytes > 0 || o->budget.max_error > 0; /* compresses several times: loaded whole */
    btf_result r = btf_source_open("library build", j->spec, &sa, budget, &in, &err);
    if (r == BTF_OK) /* views: one block of views in memory */
        r = budget     ? btf_lod_budget_compress(in.whole, &o->pca, &pkg, &o->budget, &lod, out, &res, &err)
            : in.whole ? btf_lod_compress(in.whole, &o->pca, &pkg, &lod, out, NULL, &err)
                       : btf_lod_compress_views(&in.views, &o->pca, &pkg, &lod, out, NULL, &err);
    if (r == BTF_OK)
        btf_source_warn_views("library build", j->spec, &in);
    btf_source_close(&in);
    stamp_path(o, j, path, sizeof path);
    if (r == BTF_OK && stamp_text(o, j, stamp, sizeof stamp) == 0)
        r = btf_fs_write_atomic(path, stamp, strlen(stamp), &err);
    if (r != BTF_OK)
        fprintf(stderr, "btf library build: %s: %s\n", j->name, err.msg);
    return r == BTF_OK ? 0 : 1;
}

/* Forks the job's process; 0, or -1 when fork fails. */
static int start_job(const library_opts *o, library_job *j)
{
    fflush(stdout);
    fflush(stderr);
    j->t0 = btf_seconds();
    j->pid = fork();
    if (j->pid == 0)
        _exit(build_one(o, j));
    return j->pid > 0 ? 0 : -1;
}

/* Waits for one running job; returns 1 if it failed, else counts it in *built. */
static int reap_job(const library_opts *o, library_job *jobs, int n, int *built)
{
    int status = 0;
    pid_t pid = wait(&status);
    for (int i = 0; i < n; i++)
        if (jobs[i].pid == pid && pid > 0) {
            jobs[i].pid = 0;
            int ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
            if (!ok)
                fprintf(stderr, "btf library build: %s: FAILED\n", jobs[i].name);
            else if (!o->quiet)
                printf("%s: built in %.1f s\n", jobs[i].name, btf_seconds() - jobs[i].t0);
            *built += ok;
            return !ok;
        }
    return 1;
}

/* Runs the jobs that are not up to date, o->jobs at once; returns the failures. */
static int run_jobs(const library_opts *o, library_job *jobs, int n, int *built, int *skipped)
{
    int running = 0, failed = 0;
    for (int i = 0; i < n; i++) {
        if (!o->force && up_to_date(o, &jobs[i])) {
            ++*skipped;
            if (!o->quiet)
                printf("%s: up to date\n", jobs[i].name);
            continue;
        }
        if (running == o->jobs)
            failed += reap_job(o, jobs, n, built), running--;
        if (start_job(o, &jobs[i]) == 0)
            running++;
        else
            failed++, fprintf(stderr, "btf library build: %s: fork: %s\n", jobs[i].name, strerror(errno));
    }
    while (running-- > 0)
        failed += reap_job(o, jobs, n, built);
    return failed;
}

/* Names every job and makes LIB and LIB/.build; 0, 1 failure, 2 usage error. */
static int prepare(const library_opts *o, library_job *jobs)
{
    for (int i = 0; i < o->n_src; i++) {
        if (job_name(o->src[i], jobs[i].name, sizeof jobs[i].name, &jobs[i].spec)) {
            fprintf(stderr, "btf library build: no valid package name in '%s' (use NAME=SRC)\n", o->src[i]);
            return 2;
        }
        for (int k = 0; k < i; k++)
            if (!strcmp(jobs[k].name, jobs[i].name)) {
                fprintf(stderr, "btf library build: two sources named '%s' (use NAME=SRC)\n", jobs[i].name);
                return 2;
            }
    }
    char dot[BTF_FS_PATH_MAX];
    snprintf(dot, sizeof dot, "%s/.build", o->out);
    if ((mkdir(o->out, 0755) && errno != EEXIST) || (mkdir(dot, 0755) && errno != EEXIST)) {
        fprintf(stderr, "btf library build: %s: %s\n", dot, strerror(errno));
        return 1;
    }
    return 0;
}

static int library_build(int argc, char **argv)
{
    library_opts o;
    memset(&o, 0, sizeof o);
    o.pca.k = 3, o.pca.components = 8, o.pkg.bits = 8, o.jobs = 1;
    o.pkg.thumbnail = BTF_PACKAGE_THUMBNAIL_SIDE; /* every package gets its poster */
    o.src = calloc((size_t)argc, sizeof *o.src);
    library_job *jobs = calloc((size_t)argc, sizeof *jobs);
    int rc = o.src && jobs ? btf_args_parse(&library_spec, argc, argv, library_option, &o) : 1;
    if (rc == 0 && o.budget.max_bytes > 0 && o.budget.max_error > 0) {
        fprintf(stderr, "btf library build: --max-bytes or --max-error, not both\n");
        rc = 2;
    }
    o.pkg.rd = !o.plain && (o.pkg.bits == 8 || o.levels == 0); /* rate-distortion steps unless asked otherwise
                                                                 * (16-bit levels: version 2 only) */
    o.pkg.lossy = o.pkg.rd && !o.lossless && o.pkg.bits == 8 ? (o.avif ? BTF_LOSSY_AVIF : BTF_LOSSY_WEBP)
                                                              : BTF_LOSSY_NONE; /* as btf compress */
    if (rc == 0 && o.avif && !o.pkg.lossy) {
        fprintf(stderr, "btf library build: --avif needs lossy textures (not --plain, --lossless or --bits 16)\n");
        rc = 2;
    }
    if (rc == 0 && (!o.out || !o.n_src)) {
        fprintf(stderr, "btf library build: %s\n", o.out ? "no SRC given" : "--out LIB is required");
        rc = 2;
    }
    if (rc == 0)
        rc = prepare(&o, jobs);
    if (rc == 0) {
        int built = 0, skipped = 0, failed = run_jobs(&o, jobs, o.n_src, &built, &skipped);
        if (!o.quiet || failed)
            printf("btf library build: %d built, %d up to date, %d failed\n", built, skipped, failed);
        rc = failed ? 1 : 0;
    }
    free(o.src);
    free(jobs);
    return rc < 0 ? 0 : rc;
}

/* `btf library publish LIB OUT [--client DIR]`: btfd's --publish mode, which reads the library
 * with the code that serves it (server/btfd_publish.c: one copy of the list, the etags and
 * the paths). Runs the btfd beside this program (BTFD in the environment overrides it) with
 * --client DIR, by default the bundle beside this program (client/, as make build writes it)
 * when there is one, else btfd's default. Returns its exit status. */
static int library_publish(int argc, char **argv)
{
    const char *client = NULL, *pos[2] = {NULL, NULL};
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            library_usage(stdout);
            return 0;
        }
        if (!strcmp(argv[i], "--client") && i + 1 < argc)
            client = argv[++i];
        else if (argv[i][0] != '-' && npos < 2)
            pos[npos++] = argv[i];
        else {
            fprintf(stderr, "btf library publish: unexpected argument '%s'\n", argv[i]);
            return 2;
        }
    }
    if (npos != 2) {
        fprintf(stderr, "btf library publish: LIB and OUT are required (btf library publish LIB OUT)\n");
        return 2;
    }
    char exe[BTF_FS_PATH_MAX], btfd[BTF_FS_PATH_MAX + 8], bundle[BTF_FS_PATH_MAX + 24];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = 0;
    char *slash = strrchr(exe, '/');
    if (slash)
        *slash = 0;
    snprintf(btfd, sizeof btfd, "%s/btfd", slash ? exe : ".");
    snprintf(bundle, sizeof bundle, "%s/client/btf-viewer.js", slash ? exe : ".");
    const char *prog = getenv("BTFD") && getenv("BTFD")[0] ? getenv("BTFD") : btfd;
    if (!client && btf_fs_size(bundle) >= 0) {
        bundle[strlen(bundle) - strlen("/btf-viewer.js")] = 0;
        client = bundle;
    }
    char *args[] = {(char *)prog, "--library", (char *)pos[0], "--publish", (char *)pos[1],
                    client ? "--client" : NULL, (char *)client, NULL};
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        execv(prog, args);
        fprintf(stderr, "btf library publish: cannot run %s: %s\n", prog, strerror(errno));
        _exit(1);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid)
        return 1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

int cmd_library(int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "build"))
        return library_build(argc - 1, argv + 1);
    if (argc >= 2 && !strcmp(argv[1], "publish"))
        return library_publish(argc - 1, argv + 1);
    if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        library_usage(stdout);
        return 0;
    }
    fprintf(stderr, "btf library: unknown subcommand '%s' (btf library build --help)\n", argc >= 2 ? argv[1] : "");
    library_usage(stderr);
    return 2;
}

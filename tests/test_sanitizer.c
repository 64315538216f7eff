/* test_sanitizer.c - what `make asan` needs of the test runner.
 *
 * The canary: with BTF_LEAK_CANARY set, its one test leaks a 162-byte block from
 * project code inside a test process, and make asan checks that LeakSanitizer
 * reported it (tests/asan_reports.sh --canary). A suppression in tests/lsan.supp that
 * matched the runner's library would hide every leak a test process makes, since
 * each such stack ends in the runner's frames. Without the variable it frees the
 * block, so the suites stay clean.
 *
 * The runner: Criterion's runner process runs no test (each runs in a worker process
 * of its own) and keeps two small blocks of its own until exit, allocated where no
 * frame but its library's is seen; under the sanitizers it is not leak-checked after
 * the tests start (the workers are). */
#include <criterion/criterion.h>
#include <criterion/hooks.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>

ReportHook(PRE_ALL)(struct criterion_test_set *tests)
{
    (void)tests;
    __lsan_disable();
}
#endif

/* n bytes, written, from a project frame (what LeakSanitizer's report names). */
static char *canary_block(size_t n)
{
    char *p = malloc(n);
    if (p)
        memset(p, 0x5a, n);
    return p;
}

Test(sanitizer, leak_canary)
{
    char *volatile p = canary_block(162);
    cr_assert_not_null(p);
    if (!getenv("BTF_LEAK_CANARY"))
        free(p);
    p = NULL;
}

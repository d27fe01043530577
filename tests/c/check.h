/* check.h - the check macros of every C unit test (plant, firmware, CANopen).
 *
 *   CHECK(cond, fmt, ...)  if cond is false: print "FAIL file:line: <message>" (printf format)
 *                          on stdout and count the failure; the test goes on
 *   CHECK_TRUE(cond)       the same with the condition's own text as the message
 *   check_failures()       number of failed checks so far
 *   check_exit_code()      what main() returns: 0 when no check failed, else 1 (a count could
 *                          wrap to 0 as an exit status)
 *   check_finish(name)     prints "name: PASSED" or "name: FAILED (n failed checks)" and
 *                          returns check_exit_code()
 *
 * Header only: every test is one translation unit. */
#ifndef TESTS_C_CHECK_H
#define TESTS_C_CHECK_H

#include <stdio.h>

static int g_check_failures = 0;

#define CHECK(cond, ...)                                \
    do {                                                \
        if (!(cond)) {                                  \
            printf("FAIL %s:%d: ", __FILE__, __LINE__); \
            printf(__VA_ARGS__);                        \
            printf("\n");                               \
            ++g_check_failures;                         \
        }                                               \
    } while (0)

#define CHECK_TRUE(cond) CHECK(cond, "%s", #cond)

static inline int check_failures(void) { return g_check_failures; }

static inline int check_exit_code(void) { return g_check_failures ? 1 : 0; }

static inline int check_finish(const char *name)
{
    if (g_check_failures)
        printf("%s: FAILED (%d failed checks)\n", name, g_check_failures);
    else
        printf("%s: PASSED\n", name);
    return check_exit_code();
}

#endif /* TESTS_C_CHECK_H */

/* test_check.h - the check macro shared by the firmware tests: print what failed, remember it. */
#ifndef TEST_CHECK_H
#define TEST_CHECK_H

#include <stdio.h>

static int g_fail = 0;

#define CHECK(cond, ...)            \
  do {                              \
    if (!(cond)) {                  \
      printf("FAIL: " __VA_ARGS__); \
      printf("\n");                 \
      g_fail = 1;                   \
    }                               \
  } while (0)

#endif /* TEST_CHECK_H */

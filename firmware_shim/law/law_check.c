/* law_check.c - `make LAW=DIR`: the user's law descriptor checked before the
 * drive runs it.  Built with -DLAW_NAME=<the law's name> and linked with the
 * firmware (the law's objects in it); run once by the Makefile.
 *
 * The drive calls `configure` when the law is selected and `step` every
 * current period (current_law.h): a NULL there would crash the drive at
 * its first period.  Its state lives in the drive, CURRENT_LAW_STATE_BYTES
 * at most: a larger state_bytes would let the law write past it (a law that
 * uses CURRENT_LAW_STATE_FITS fails its compile instead).  Each failure is
 * one line on stderr naming the member and the rule; exit 1. */
#include <stdio.h>

#include "current_law.h"

#define LAW_STR2(x) #x
#define LAW_STR(x) LAW_STR2(x)
#define LAW_SYM2(n) current_law_##n
#define LAW_SYM(n) LAW_SYM2(n)

extern const current_law_t LAW_SYM(LAW_NAME);

int main(void)
{
    const current_law_t *law = &LAW_SYM(LAW_NAME);
    const char *sym = "current_law_" LAW_STR(LAW_NAME);
    int bad = 0;
    if (law->configure == NULL) {
        fprintf(stderr, "law_check: %s.configure is NULL: the drive calls it when the law is selected\n", sym);
        bad = 1;
    }
    if (law->step == NULL) {
        fprintf(stderr, "law_check: %s.step is NULL: the drive calls it every current period\n", sym);
        bad = 1;
    }
    if (law->state_bytes > CURRENT_LAW_STATE_BYTES) {
        fprintf(stderr,
                "law_check: %s.state_bytes = %lu: expected sizeof your state, at most %lu "
                "(CURRENT_LAW_STATE_BYTES; CURRENT_LAW_STATE_FITS(state_t) checks it at compile time)\n",
                sym, (unsigned long)law->state_bytes, (unsigned long)CURRENT_LAW_STATE_BYTES);
        bad = 1;
    }
    return bad;
}

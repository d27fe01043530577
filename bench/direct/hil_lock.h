/* hil_lock.h - the one lock of direct mode (recursive, priority inheritance). Every hil_* entry point Python calls
 * takes it, so that Python's threads never meet the nodes' threads of a real-time run in the middle of a frame; a
 * node's thread holds it to process its frames and timers, never while it sleeps (hil_wait). The bottom of the
 * direct mode's files: it uses none of them. */
#ifndef HIL_LOCK_H
#define HIL_LOCK_H

#include <pthread.h>
#include <time.h>

void hil_lock(void);
void hil_unlock(void);
/* Wait on cv (a CLOCK_MONOTONIC condition) until `until` at the latest, the lock (held) released meanwhile. */
void hil_wait(pthread_cond_t *cv, const struct timespec *until);

#endif /* HIL_LOCK_H */

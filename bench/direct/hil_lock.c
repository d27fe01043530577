/* hil_lock.c - the one lock of direct mode (see hil_lock.h). */
#define _GNU_SOURCE /* the recursive, priority-inheriting lock */
#include "hil_lock.h"

static pthread_mutex_t g_lock;
static pthread_once_t g_lock_once = PTHREAD_ONCE_INIT;

static void lock_init(void)
{
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_settype(&ma, PTHREAD_MUTEX_RECURSIVE);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&g_lock, &ma);
}

void hil_lock(void)
{
    pthread_once(&g_lock_once, lock_init);
    pthread_mutex_lock(&g_lock);
}
void hil_unlock(void) { pthread_mutex_unlock(&g_lock); }
void hil_wait(pthread_cond_t *cv, const struct timespec *until) { (void)pthread_cond_timedwait(cv, &g_lock, until); }

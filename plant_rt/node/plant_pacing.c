/* plant_pacing.c - see plant_pacing.h. */
#include "plant_pacing.h"

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#define GUARD_US 30      /* stop serving frames this long before a deadline */
#define SERVE_MIN_US 200 /* serve frames between deadlines only if this much time is left */
#define IDLE_WAIT_US 10000

#if defined(__x86_64__) || defined(__i386__)
#define CPU_RELAX() __builtin_ia32_pause()
#elif defined(__aarch64__) || defined(__arm__)
#define CPU_RELAX() __asm__ volatile("yield")
#else
#define CPU_RELAX() ((void)0)
#endif

int64_t plant_pacing_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void sleep_until_ns(int64_t t_ns, const plant_pacing_io_t *io)
{
    struct timespec ts = {.tv_sec = (time_t)(t_ns / 1000000000LL), .tv_nsec = (long)(t_ns % 1000000000LL)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
        if (io->stop(io->user)) return;
    }
}

/* The CPUs this process may run on (taskset, cpusets, isolcpus given to it): the first and the last. */
static int allowed_cpus(int *first, int *last)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) != 0) return 0;
    *first = *last = -1;
    for (int c = 0; c < CPU_SETSIZE; ++c) {
        if (!CPU_ISSET(c, &set)) continue;
        if (*first < 0) *first = c;
        *last = c;
    }
    return CPU_COUNT(&set);
}

int plant_pacing_default_cpu(void)
{
    int first = -1, last = -1;
    return allowed_cpus(&first, &last) >= 2 ? first : -1;
}

int plant_pacing_other_cpu(void)
{
    int first = -1, last = -1;
    return allowed_cpus(&first, &last) >= 2 ? last : -1;
}

int plant_pacing_pin(int cpu)
{
    if (cpu < 0) return 0;
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    return sched_setaffinity(0, sizeof set, &set) == 0 ? 0 : errno; /* Linux: the calling thread */
}

const char *plant_pacing_priority(int priority, int cpu)
{
    static char line[512];
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = priority;
    int fifo = sched_setscheduler(0, SCHED_FIFO, &sp) == 0; /* Linux: the calling thread */
    int fifo_err = fifo ? 0 : errno;
    /* the memory once per process (MCL_FUTURE keeps it so: a second call would walk every page again) */
    static int locked = -1, lock_err;
    if (locked < 0) {
        locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
        lock_err = locked ? 0 : errno;
    }
    /* CPU idle states held off while the process runs, as cyclictest does (/dev/cpu_dma_latency = 0): a deep
     * idle state's exit latency would add to every deadline's */
    static int dma_fd = -2;
    if (dma_fd == -2) {
        dma_fd = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
        const int32_t zero = 0;
        if (dma_fd >= 0 && write(dma_fd, &zero, sizeof zero) != (ssize_t)sizeof zero) {
            close(dma_fd);
            dma_fd = -1;
        }
    }
    int pin_err = plant_pacing_pin(cpu);
    char where[80] = "";
    if (cpu >= 0 && pin_err == 0) snprintf(where, sizeof where, ", on CPU %d", cpu);
    if (cpu >= 0 && pin_err != 0) snprintf(where, sizeof where, ", not kept on CPU %d (%s)", cpu, strerror(pin_err));
    const char *idle = dma_fd >= 0 ? ", CPU idle states held off" : "";
    if (fifo && locked) {
        snprintf(line, sizeof line, "SCHED_FIFO priority %d, memory locked%s%s", priority, idle, where);
    } else {
        char fifo_text[96] = "", lock_text[96] = "";
        if (!fifo) snprintf(fifo_text, sizeof fifo_text, "SCHED_FIFO not permitted (%s)", strerror(fifo_err));
        if (!locked) snprintf(lock_text, sizeof lock_text, "mlockall not permitted (%s)", strerror(lock_err));
        snprintf(line, sizeof line,
                 "%s%s%s%s%s: timing may jitter; grant both from the shell that runs the bench with "
                 "`sudo prlimit --pid $$ --rtprio=99 --memlock=unlimited`",
                 fifo_text, !fifo && !locked ? ", " : "", lock_text, idle, where);
    }
    return line;
}

static struct {
    pthread_t th;
    int cpu, running;
    volatile int keep;
} A;

static void *awake_main(void *arg)
{
    (void)arg;
    (void)pthread_setname_np(pthread_self(), "hil-awake"); /* named in top -H, perf sched and ftrace */
    (void)plant_pacing_pin(A.cpu);
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    (void)pthread_setschedparam(pthread_self(), SCHED_IDLE, &sp);
    while (__atomic_load_n(&A.keep, __ATOMIC_ACQUIRE)) CPU_RELAX();
    return NULL;
}

int plant_pacing_awake_start(int cpu)
{
    if (cpu < 0 || A.running) return A.running;
    A.cpu = cpu;
    __atomic_store_n(&A.keep, 1, __ATOMIC_RELEASE);
    A.running = pthread_create(&A.th, NULL, awake_main, NULL) == 0;
    return A.running;
}

void plant_pacing_awake_stop(void)
{
    if (!A.running) return;
    __atomic_store_n(&A.keep, 0, __ATOMIC_RELEASE);
    pthread_join(A.th, NULL);
    A.running = 0;
}

void plant_pacing_loop(plant_app_t *app, const plant_pacing_io_t *io)
{
    int64_t deadline_ns = 0;
    while (!io->stop(io->user) && plant_app_realtime_mode(app)) {
        if (!plant_app_running(app)) {
            /* holding: serve SDO/NMT, restart the deadline grid when running again */
            io->serve_until(io->user, plant_pacing_now_ns() + (int64_t)IDLE_WAIT_US * 1000);
            deadline_ns = 0;
            continue;
        }
        int64_t period_ns = plant_app_period_ns(app);
        if (deadline_ns == 0) deadline_ns = plant_pacing_now_ns() + period_ns;
        /* short periods: one absolute sleep per period (each wake-up costs tens of us) */
        if (deadline_ns - plant_pacing_now_ns() > (int64_t)SERVE_MIN_US * 1000)
            io->serve_until(io->user, deadline_ns - (int64_t)GUARD_US * 1000);
        sleep_until_ns(deadline_ns, io);
        int64_t now_ns = io->tick(io->user, deadline_ns);
        deadline_ns += plant_app_period_ns(app);                                      /* Ts applied at this SYNC */
        if (deadline_ns < now_ns - 100 * period_ns) deadline_ns = now_ns + period_ns; /* far behind: re-grid */
    }
}

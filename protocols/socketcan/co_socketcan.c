/* co_socketcan.c - Linux SocketCAN driver (raw CAN_RAW sockets). */
#include "co_socketcan.h"

#include <errno.h>
#include <stdbool.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

int co_socketcan_open(const char *ifname, int rcvbuf_bytes)
{
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        fprintf(stderr,
                "socket(PF_CAN): %s (errno %d): this kernel has no SocketCAN; "
                "run inside `bench vm -- ...`\n",
                strerror(errno), errno);
        return -1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
        fprintf(stderr, "CAN interface '%s' not found: %s\n", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    if (rcvbuf_bytes > 0) {
        /* SO_RCVBUFFORCE needs CAP_NET_ADMIN; fall back to SO_RCVBUF. */
        if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf_bytes, sizeof rcvbuf_bytes) < 0)
            (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf_bytes, sizeof rcvbuf_bytes);
    }
    int one = 1;
    (void)setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one);
    /* CAN FD frames in and out where the link carries them (MTU 72): a node whose PDOs are classic still gets
     * them (a classic-only link never has any). */
    (void)setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &one, sizeof one);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        fprintf(stderr, "bind(%s): %s\n", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

int co_socketcan_send(void *user, const co_frame_t *frame)
{
    int fd = *(const int *)user;
    struct canfd_frame cf; /* a classic frame is its first CAN_MTU bytes (struct can_frame's layout) */
    memset(&cf, 0, sizeof cf);
    cf.can_id = frame->cob_id & CAN_SFF_MASK;
    if (frame->cob_id & CO_FRAME_RTR) cf.can_id |= CAN_RTR_FLAG;
    bool fd_frame = (frame->flags & CO_FRAME_FDF) != 0u;
    size_t size = fd_frame ? CANFD_MTU : CAN_MTU;
    cf.len = frame->dlc > (fd_frame ? CANFD_MAX_DLEN : CAN_MAX_DLEN) ? (fd_frame ? CANFD_MAX_DLEN : CAN_MAX_DLEN)
                                                                     : frame->dlc;
    if (fd_frame) {
        cf.flags = (frame->flags & CO_FRAME_BRS) ? CANFD_BRS : 0;
#ifdef CANFD_FDF
        cf.flags |= CANFD_FDF;
#endif
    }
    memcpy(cf.data, frame->data, cf.len);
    for (int tries = 0; tries < 1000; ++tries) {
        ssize_t n = write(fd, &cf, size);
        if (n == (ssize_t)size) return 0;
        if (n < 0 && (errno == ENOBUFS || errno == EAGAIN)) {
            /* Transmit queue full: back off briefly, as a CAN controller would wait for a free mailbox. */
            struct timespec ts = {0, 20000};
            nanosleep(&ts, NULL);
            continue;
        }
        if (n < 0 && errno == EINVAL && fd_frame)
            fprintf(stderr,
                    "CAN write: a CAN FD frame (0x%03X, %u bytes) on a link that carries classic frames only "
                    "(MTU 16): `ip link set IF down && ip link set IF mtu 72 up` for a vcan, `ip link set IF type "
                    "can bitrate B dbitrate D fd on` (the link down) for an adapter\n",
                    (unsigned)(frame->cob_id & CAN_SFF_MASK), (unsigned)cf.len);
        else
            fprintf(stderr, "CAN write: %s\n", strerror(errno));
        return -1;
    }
    fprintf(stderr, "CAN write: transmit queue stayed full\n");
    return -1;
}

int co_socketcan_recv(int fd, co_frame_t *frame, int64_t timeout_us, int64_t *ts_ns)
{
    struct canfd_frame cf; /* a classic frame fills its first CAN_MTU bytes */
    char ctrl[CMSG_SPACE(sizeof(struct timeval))];
    struct iovec iov = {.iov_base = &cf, .iov_len = sizeof cf};
    struct msghdr msg;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = ctrl;
    msg.msg_controllen = sizeof ctrl;
    /* Frames come in bursts (SYNC + measurements): try a non-blocking read first and only
     * wait (ppoll, microsecond timeout) when nothing is queued. Each system call counts
     * under emulation. */
    ssize_t n = recvmsg(fd, &msg, MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        if (timeout_us == 0) return 0;
        struct pollfd p = {.fd = fd, .events = POLLIN, .revents = 0};
        struct timespec ts = {(time_t)(timeout_us / 1000000), (long)(timeout_us % 1000000) * 1000L};
        int r = ppoll(&p, 1, timeout_us < 0 ? NULL : &ts, NULL);
        if (r == 0) return 0;
        if (r < 0) return errno == EINTR ? 0 : -1;
        msg.msg_controllen = sizeof ctrl;
        n = recvmsg(fd, &msg, MSG_DONTWAIT);
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
    }
    if (n != (ssize_t)CAN_MTU && n != (ssize_t)CANFD_MTU) return n < 0 && errno == EINTR ? 0 : -1;
    if (cf.can_id & (CAN_ERR_FLAG | CAN_EFF_FLAG)) return 0; /* only 11-bit CANopen frames */
    bool fd_frame = n == (ssize_t)CANFD_MTU;
    uint8_t max = fd_frame ? (uint8_t)CO_FRAME_MAX_DATA : 8u;
    frame->cob_id = cf.can_id & CAN_SFF_MASK;
    if (cf.can_id & CAN_RTR_FLAG) frame->cob_id |= CO_FRAME_RTR;
    if (cf.len > max) return 0; /* longer than this build's frames hold: not for this node */
    frame->dlc = cf.len;
    frame->flags = fd_frame ? (uint8_t)(CO_FRAME_FDF | ((cf.flags & CANFD_BRS) ? CO_FRAME_BRS : 0u)) : 0u;
    memset(frame->data, 0, 8);
    memcpy(frame->data, cf.data, frame->dlc);
    if (ts_ns) {
        *ts_ns = 0;
        for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
            if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMP) {
                struct timeval tv;
                memcpy(&tv, CMSG_DATA(c), sizeof tv);
                *ts_ns = (int64_t)tv.tv_sec * 1000000000LL + (int64_t)tv.tv_usec * 1000LL;
            }
        }
    }
    return 1;
}

int64_t co_socketcan_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000LL + ts.tv_nsec / 1000;
}

/* drive_firmware.c - the drive node's portable main loop (see drive_firmware.h).
 * Portable: no OS headers, no allocation. */
#include "drive_firmware.h"

#include <stddef.h>

#include "drive_port.h"
#include "od_drive.h"

static int port_tx(void *user, const co_frame_t *frame)
{
    (void)user;
    return drive_port_can_send(frame) == 0 ? 0 : -1;
}

static uint32_t port_cycles(void *user)
{
    (void)user;
    return drive_port_cycles();
}

void drive_firmware_init(drive_firmware_t *fw, uint8_t node_id)
{
    fw->frames_in = 0u;
    drive_app_init(&fw->app);
    co_node_init(&fw->node, &od_drive, node_id, port_tx, NULL, drive_app_hooks(), &fw->app, drive_port_time_us());
    drive_app_bind(&fw->app, &fw->node);
    const uint32_t hz = drive_port_cycle_clock_Hz();
    drive_app_set_cycle_counter(&fw->app, hz != 0u ? port_cycles : NULL, NULL, hz);
    drive_app_set_overrun_check(&fw->app, hz != 0u ? 1u : 0u); /* bare metal: the counter's cycles are the step's */
}

uint32_t drive_firmware_poll(drive_firmware_t *fw)
{
    uint32_t n = 0u;
    co_frame_t f;
    while (drive_port_can_receive(&f)) {
        co_node_process(&fw->node, &f, drive_port_time_us());
        ++n;
    }
    co_node_tick(&fw->node, drive_port_time_us());
    fw->frames_in += n;
    return n;
}

void drive_firmware_run(drive_firmware_t *fw)
{
    for (;;) {
        if (drive_firmware_poll(fw) == 0u) drive_port_idle();
    }
}

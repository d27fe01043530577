/* main.c - the drive firmware on the MPS2 AN386 image (Cortex-M4F; QEMU mps2-an386).
 *
 * CANopen node OD_DRIVE_DEFAULT_NODE_ID (drive.eds) over SLCAN on UART0; a boot
 * line on UART1.  Everything else is the portable firmware: drive_firmware_run. */
#include <stdint.h>

#include "drive_firmware.h"
#include "drive_port_mps2.h"
#include "mps2_uart.h"
#include "od_drive.h"

static drive_firmware_t g_fw; /* ~36 KiB with the trace buffer: .bss */

int main(void)
{
    drive_port_mps2_init();
    mps2_uart_console("drive_mcu: node ");
    mps2_uart_console_u32(OD_DRIVE_DEFAULT_NODE_ID);
    mps2_uart_console(", SLCAN on UART0, state ");
    mps2_uart_console_u32((uint32_t)sizeof g_fw);
    mps2_uart_console(" bytes\n");
    drive_firmware_init(&g_fw, (uint8_t)OD_DRIVE_DEFAULT_NODE_ID);
    drive_firmware_run(&g_fw);
    return 0;
}

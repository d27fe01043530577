/* cia402_device.h - the CiA 402 power drive system state machine, on its own.
 *
 * PORTABLE (no OS headers, no allocation, no CANopen): controlword in, state
 * and statusword out, in the style of CANopenNode's services (one struct,
 * initialised with only what it needs).  drive_app.c is the glue: it feeds the
 * controlword (0x6040), reports faults and "stopped", and gates the power
 * stage with cia402_device_power_enabled().
 *
 * States and transitions (CiA 402-2, 6.4; numbers as in the standard):
 *   0, 1   START -> NOT READY TO SWITCH ON -> SWITCH ON DISABLED (init)
 *   2      SWITCH ON DISABLED  -- shutdown (0bxxxx_x110) -->        READY TO SWITCH ON
 *   3      READY TO SWITCH ON  -- switch on (0bxxxx_0111) -->       SWITCHED ON
 *   3+4    READY TO SWITCH ON  -- switch on + enable (0bxxxx_1111) --> OPERATION ENABLED
 *   4      SWITCHED ON         -- enable operation (0bxxxx_1111) --> OPERATION ENABLED
 *   5      OPERATION ENABLED   -- disable operation (0bxxxx_0111) --> SWITCHED ON
 *   6, 8   SWITCHED ON / OPERATION ENABLED -- shutdown --> READY TO SWITCH ON
 *   7, 9, 10, 12  -- disable voltage (0bxxxx_xx0x) --> SWITCH ON DISABLED
 *   7, 10  READY TO SWITCH ON / SWITCHED ON -- quick stop (0bxxxx_x01x) --> SWITCH ON DISABLED
 *   11     OPERATION ENABLED   -- quick stop --> QUICK STOP ACTIVE
 *   12     QUICK STOP ACTIVE   -- stopped, option code 1, 2 --> SWITCH ON DISABLED
 *   16     QUICK STOP ACTIVE   -- enable operation, option code 5, 6 --> OPERATION ENABLED
 *   13, 14 any state -- fault --> FAULT REACTION ACTIVE --> FAULT (the reaction,
 *          0 V, is immediate here, so 14 follows 13 at once)
 *   15     FAULT               -- fault reset (rising edge of bit 7) --> SWITCH ON DISABLED
 * Quick stop option code 0: transition 11 ends in SWITCH ON DISABLED at once.
 * A controlword with bit 7 set commands nothing outside FAULT (the command
 * table of CiA 402 has no entry for it). */
#ifndef CIA402_DEVICE_H
#define CIA402_DEVICE_H

#include <stdint.h>

typedef enum {
    CIA402_NOT_READY_TO_SWITCH_ON = 0,
    CIA402_SWITCH_ON_DISABLED,
    CIA402_READY_TO_SWITCH_ON,
    CIA402_SWITCHED_ON,
    CIA402_OPERATION_ENABLED,
    CIA402_QUICK_STOP_ACTIVE,
    CIA402_FAULT_REACTION_ACTIVE,
    CIA402_FAULT
} cia402_state_t;

/* Controlword bits (CiA 402-2 6.4.1). */
#define CIA402_CW_SWITCH_ON 0x0001u
#define CIA402_CW_ENABLE_VOLTAGE 0x0002u
#define CIA402_CW_QUICK_STOP 0x0004u /* 0 = quick stop */
#define CIA402_CW_ENABLE_OPERATION 0x0008u
#define CIA402_CW_FAULT_RESET 0x0080u

/* Statusword bits (CiA 402-2 6.4.2). */
#define CIA402_SW_READY_TO_SWITCH_ON 0x0001u
#define CIA402_SW_SWITCHED_ON 0x0002u
#define CIA402_SW_OPERATION_ENABLED 0x0004u
#define CIA402_SW_FAULT 0x0008u
#define CIA402_SW_VOLTAGE_ENABLED 0x0010u
#define CIA402_SW_QUICK_STOP 0x0020u /* 0 = quick stop active */
#define CIA402_SW_SWITCH_ON_DISABLED 0x0040u
#define CIA402_SW_REMOTE 0x0200u /* the controlword is processed */

/* Modes of operation (0x6060/0x6061) of this drive: CiA 402's codes, and -1 its
 * manufacturer-specific current mode (the papers' id/iq references). */
#define CIA402_MODE_MANUFACTURER_CURRENT (-1)
#define CIA402_MODE_NONE 0
#define CIA402_MODE_CST 10

typedef struct {
    int16_t quick_stop_option; /* 0x605A: 0, 1, 2, 5, 6 (3, 4 are refused by the glue) */
} cia402_config_t;

typedef struct {
    cia402_config_t cfg;
    uint8_t state;        /* cia402_state_t */
    uint8_t reset_armed;  /* bit 7 was 0 in the last controlword: a 1 is a rising edge */
    uint16_t transitions; /* state changes since init (any: the glue sends the statusword on each) */
} cia402_device_t;

/* START -> NOT READY TO SWITCH ON -> SWITCH ON DISABLED (transitions 0 and 1). */
void cia402_device_init(cia402_device_t *dev, const cia402_config_t *cfg);

/* A controlword was written.  fault_reset_allowed: 0 while the cause of the
 * fault persists: the reset is then refused and its edge consumed (CiA 402
 * resets on the rising edge of bit 7 only: a master holding 0x80, e.g. in a
 * cyclic RPDO, gets no reset when the cause clears; it must send bit 7 = 0,
 * then 1 again).  Returns 1 if the state changed. */
int cia402_device_controlword(cia402_device_t *dev, uint16_t controlword, int fault_reset_allowed);

/* A fault: transitions 13 and 14 (no effect in FAULT). Returns 1 if the state changed. */
int cia402_device_fault(cia402_device_t *dev);

/* A fault reset by other means (the manufacturer's 0x2209:05 clear): FAULT ->
 * SWITCH ON DISABLED (transition 15). Returns 1 if the state changed. */
int cia402_device_fault_reset(cia402_device_t *dev);

/* QUICK STOP ACTIVE and the motor stopped: transition 12 for option codes 1, 2.
 * Returns 1 if the state changed. */
int cia402_device_stopped(cia402_device_t *dev);

/* Leave every enabled state for SWITCH ON DISABLED (the communication-loss
 * reaction "disable voltage" of 0x6007 option 3; used when NMT leaves
 * OPERATIONAL). Returns 1 if the state changed. */
int cia402_device_disable_voltage(cia402_device_t *dev);

uint16_t cia402_device_statusword(const cia402_device_t *dev);

/* The control may act on the motor: OPERATION ENABLED or QUICK STOP ACTIVE. */
int cia402_device_power_enabled(const cia402_device_t *dev);

#endif /* CIA402_DEVICE_H */

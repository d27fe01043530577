/* cia402_device.c - the CiA 402 state machine (see cia402_device.h). Portable. */
#include "cia402_device.h"

static int set_state(cia402_device_t *dev, cia402_state_t s)
{
    if (dev->state == (uint8_t)s) return 0;
    dev->state = (uint8_t)s;
    ++dev->transitions;
    return 1;
}

void cia402_device_init(cia402_device_t *dev, const cia402_config_t *cfg)
{
    dev->cfg = *cfg;
    dev->state = (uint8_t)CIA402_NOT_READY_TO_SWITCH_ON; /* transition 0 */
    dev->reset_armed = 1u;
    dev->transitions = 0u;
    (void)set_state(dev, CIA402_SWITCH_ON_DISABLED); /* transition 1: the self-test is the init itself */
}

/* The commands of CiA 402-2 Table 33 (bits 7, 3, 2, 1, 0). */
typedef enum { CMD_NONE, CMD_SHUTDOWN, CMD_SWITCH_ON, CMD_SWITCH_ON_ENABLE, CMD_DISABLE_VOLTAGE, CMD_QUICK_STOP } cmd_t;

static cmd_t decode(uint16_t cw)
{
    if (cw & CIA402_CW_FAULT_RESET) return CMD_NONE;                  /* fault reset: handled apart, FAULT only */
    if (!(cw & CIA402_CW_ENABLE_VOLTAGE)) return CMD_DISABLE_VOLTAGE; /* 0bxxxx_xx0x */
    if (!(cw & CIA402_CW_QUICK_STOP)) return CMD_QUICK_STOP;          /* 0bxxxx_x01x */
    if (!(cw & CIA402_CW_SWITCH_ON)) return CMD_SHUTDOWN;             /* 0bxxxx_x110 */
    if (!(cw & CIA402_CW_ENABLE_OPERATION)) return CMD_SWITCH_ON;     /* 0bxxxx_0111 (also "disable operation") */
    return CMD_SWITCH_ON_ENABLE;                                      /* 0bxxxx_1111 */
}

static int stays_in_quick_stop(int16_t option) { return option == 5 || option == 6; }

int cia402_device_controlword(cia402_device_t *dev, uint16_t controlword, int fault_reset_allowed)
{
    const int bit7 = (controlword & CIA402_CW_FAULT_RESET) != 0u;
    const int rising = bit7 && dev->reset_armed;
    if (!bit7) dev->reset_armed = 1u;
    switch ((cia402_state_t)dev->state) {
    case CIA402_FAULT:
        if (!rising) return 0;
        dev->reset_armed = 0u; /* the edge is consumed, reset or refused: holding bit 7 never resets later */
        return fault_reset_allowed ? set_state(dev, CIA402_SWITCH_ON_DISABLED) : 0; /* 15 */
    case CIA402_FAULT_REACTION_ACTIVE:
    case CIA402_NOT_READY_TO_SWITCH_ON: return 0;
    default: break;
    }
    if (bit7) dev->reset_armed = 0u;
    switch (decode(controlword)) {
    case CMD_NONE: return 0;
    case CMD_DISABLE_VOLTAGE: return set_state(dev, CIA402_SWITCH_ON_DISABLED); /* 7, 9, 10, 12 */
    case CMD_QUICK_STOP:
        switch ((cia402_state_t)dev->state) {
        case CIA402_READY_TO_SWITCH_ON:
        case CIA402_SWITCHED_ON: return set_state(dev, CIA402_SWITCH_ON_DISABLED); /* 7, 10 */
        case CIA402_OPERATION_ENABLED:                                             /* 11 */
            return set_state(dev,
                             dev->cfg.quick_stop_option == 0 ? CIA402_SWITCH_ON_DISABLED : CIA402_QUICK_STOP_ACTIVE);
        default: return 0;
        }
    case CMD_SHUTDOWN:
        switch ((cia402_state_t)dev->state) {
        case CIA402_SWITCH_ON_DISABLED:                                                  /* 2 */
        case CIA402_SWITCHED_ON:                                                         /* 6 */
        case CIA402_OPERATION_ENABLED: return set_state(dev, CIA402_READY_TO_SWITCH_ON); /* 8 */
        default: return 0;
        }
    case CMD_SWITCH_ON:
        switch ((cia402_state_t)dev->state) {
        case CIA402_READY_TO_SWITCH_ON:                                           /* 3 */
        case CIA402_OPERATION_ENABLED: return set_state(dev, CIA402_SWITCHED_ON); /* 5 */
        default: return 0;
        }
    case CMD_SWITCH_ON_ENABLE:
        switch ((cia402_state_t)dev->state) {
        case CIA402_READY_TO_SWITCH_ON:                                           /* 3 + 4 */
        case CIA402_SWITCHED_ON: return set_state(dev, CIA402_OPERATION_ENABLED); /* 4 */
        case CIA402_QUICK_STOP_ACTIVE:                                            /* 16 */
            return stays_in_quick_stop(dev->cfg.quick_stop_option) ? set_state(dev, CIA402_OPERATION_ENABLED) : 0;
        default: return 0;
        }
    }
    return 0;
}

int cia402_device_fault(cia402_device_t *dev)
{
    if (dev->state == (uint8_t)CIA402_FAULT) return 0;
    (void)set_state(dev, CIA402_FAULT_REACTION_ACTIVE); /* 13 */
    (void)set_state(dev, CIA402_FAULT);                 /* 14: the reaction (0 V) is done by the caller */
    return 1;
}

int cia402_device_fault_reset(cia402_device_t *dev)
{
    if (dev->state != (uint8_t)CIA402_FAULT) return 0;
    return set_state(dev, CIA402_SWITCH_ON_DISABLED); /* 15 */
}

int cia402_device_stopped(cia402_device_t *dev)
{
    if (dev->state != (uint8_t)CIA402_QUICK_STOP_ACTIVE || stays_in_quick_stop(dev->cfg.quick_stop_option)) return 0;
    return set_state(dev, CIA402_SWITCH_ON_DISABLED); /* 12 */
}

int cia402_device_disable_voltage(cia402_device_t *dev)
{
    switch ((cia402_state_t)dev->state) {
    case CIA402_READY_TO_SWITCH_ON:
    case CIA402_SWITCHED_ON:
    case CIA402_OPERATION_ENABLED:
    case CIA402_QUICK_STOP_ACTIVE: return set_state(dev, CIA402_SWITCH_ON_DISABLED);
    default: return 0;
    }
}

uint16_t cia402_device_statusword(const cia402_device_t *dev)
{
    uint16_t sw = 0u;
    switch ((cia402_state_t)dev->state) {
    case CIA402_NOT_READY_TO_SWITCH_ON: sw = 0x0000u; break;
    case CIA402_SWITCH_ON_DISABLED: sw = CIA402_SW_SWITCH_ON_DISABLED; break;
    case CIA402_READY_TO_SWITCH_ON: sw = CIA402_SW_QUICK_STOP | CIA402_SW_READY_TO_SWITCH_ON; break;
    case CIA402_SWITCHED_ON:
        sw = CIA402_SW_QUICK_STOP | CIA402_SW_VOLTAGE_ENABLED | CIA402_SW_SWITCHED_ON | CIA402_SW_READY_TO_SWITCH_ON;
        break;
    case CIA402_OPERATION_ENABLED:
        sw = CIA402_SW_QUICK_STOP | CIA402_SW_VOLTAGE_ENABLED | CIA402_SW_OPERATION_ENABLED | CIA402_SW_SWITCHED_ON |
             CIA402_SW_READY_TO_SWITCH_ON;
        break;
    case CIA402_QUICK_STOP_ACTIVE:
        sw = CIA402_SW_VOLTAGE_ENABLED | CIA402_SW_OPERATION_ENABLED | CIA402_SW_SWITCHED_ON |
             CIA402_SW_READY_TO_SWITCH_ON;
        break;
    case CIA402_FAULT_REACTION_ACTIVE:
        sw = CIA402_SW_FAULT | CIA402_SW_OPERATION_ENABLED | CIA402_SW_SWITCHED_ON | CIA402_SW_READY_TO_SWITCH_ON;
        break;
    case CIA402_FAULT: sw = CIA402_SW_FAULT; break;
    }
    return (uint16_t)(sw | CIA402_SW_REMOTE);
}

int cia402_device_power_enabled(const cia402_device_t *dev)
{
    return dev->state == (uint8_t)CIA402_OPERATION_ENABLED || dev->state == (uint8_t)CIA402_QUICK_STOP_ACTIVE;
}

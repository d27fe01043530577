/* current_law.h - the face of a current control law: what the drive needs of
 * it, one registry row per law.
 *
 * The drive (drive_core.c) knows no law.  It looks the selected one up in the
 * registry by the value of Controller.controller (0x2200:01), and calls it once
 * per current period:
 *
 *   configure  derive its gains from the drive's configuration (the model the
 *              controller believes in: R_hat_ohm, Ld_hat_H, Lq_hat_H,
 *              psi_hat_Wb, Vmax_V, Ts_s, ...) and from the parameters of its own
 *              EDS record; `switched` = 1 when it was just selected (start from
 *              reset), else keep its memories (bumpless);
 *   step       the output: measured dq currents and references of sample k in,
 *              the stator-frame command held over [k+1, k+2] out, limited by the
 *              law to Vmax_V;
 *   commit     the update: told the dq command actually applied (its decoupled
 *              part), the law updates its memories (anti-windup, histories,
 *              estimators, identification); optional;
 *   reset      forget the memories (open loop, safe state: the command was not
 *              the law's); identified model values may be kept;
 *   status     write the status entries of its EDS record (the read-only ones):
 *              what it shows and traces (its record's Trace= entries, a
 *              scenario's [trace]), the one path of a law's quantities.
 *
 * motulator's blocks (output() then update()) and moteus' SimplePI (Config /
 * State / Apply) are the model.  A law is a folder of C files and one EDS
 * record (law.eds): the record's section names the law in its CurrentLaws key, and
 * protocols/gen_od.py writes the registry (current_law_table.c) from the
 * EDS's Controller.controller value names: the row of value name N is bound to
 * the descriptor `const current_law_t current_law_N` of the law's C file.  The
 * papers' laws are registered the same way (docs/YOUR_CONTROLLER.md).
 *
 * What a law may do: float32 arithmetic on its own state, <math.h>, dq_math.h.  What it
 * may not: allocate, include an OS header, keep pointers to the drive, block.
 * Its state lives in the drive (CURRENT_LAW_STATE_BYTES, no allocation); its
 * record is the EDS record's generated C struct (od_drive_fields.h). */
#ifndef CURRENT_LAW_H
#define CURRENT_LAW_H

#include <math.h>
#include <stddef.h> /* NULL for a descriptor's unset members */
#include <stdint.h>

#include "dq_math.h"
#include "drive_config.h"
#include "od_drive_fields.h"

/* Room for the selected law's state and its record in drive_t. */
#define CURRENT_LAW_STATE_BYTES 2048u
#define CURRENT_LAW_RECORD_BYTES 256u

/* Sample k, as the law sees it. */
typedef struct {
    float i_d_A, i_q_A;       /* measured currents, dq frame of theta_e(k) */
    float id_ref_A, iq_ref_A; /* references of this step: the targets of i(k+2) */
    float theta_e_rad;        /* electrical angle at the sample */
    float omega_e_rad_s;      /* electrical speed (the drive's estimate) */
} current_law_in_t;

/* The command.  A law sets every field; the drive applies v_alpha/v_beta. */
typedef struct {
    float v_d_V, v_q_V;           /* dq command in the frame of theta_e(k), after the limit */
    float v_d_star_V, v_q_star_V; /* its decoupled part (v_dq minus the feed-forward) */
    float v_d_ff_V, v_q_ff_V;     /* feed-forward part (0 for a law without one) */
    float v_alpha_V, v_beta_V;    /* stator-frame command held over [k+1, k+2] */
    uint8_t v_limited;            /* 1 when the law limited the vector to Vmax_V */
    float v_after_limit_V;        /* the most it added to each phase after the limit (a dead-time compensation's
                                     amplitude), 0 for none: the drive accepts |v| <= Vmax_V + 2 v_after_limit_V */
} current_law_out_t;

typedef enum {
    CURRENT_LAW_OK = 0,
    CURRENT_LAW_INCOMPATIBLE, /* contradicts the drive's configuration (SDO abort 0x0604 0043) */
    CURRENT_LAW_NOT_NOW,      /* refused in the present state (SDO abort 0x0800 0022) */
    CURRENT_LAW_INVALID,      /* a value the law does not take (SDO abort 0x0609 0030) */
    CURRENT_LAW_NOT_COMMAND,  /* command(): the entry is a parameter, not a command */
} current_law_verdict_t;

typedef struct current_law {
    uint32_t state_bytes;      /* sizeof its state, <= CURRENT_LAW_STATE_BYTES */
    uint8_t single_inductance; /* 1: a surface-mounted law (L_hat = Lq_hat_H), needs a non-salient model */
    void (*configure)(void *state, const drive_config_t *cfg, const void *record, int switched);
    void (*step)(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                 current_law_out_t *out);
    /* optional (NULL: nothing to do) */
    void (*commit)(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                   const current_law_out_t *applied);
    void (*speed_step)(void *state, const drive_config_t *cfg, const void *record); /* at the outer loops' rate */
    void (*reset)(void *state);
    void (*status)(const void *state, const drive_config_t *cfg, void *record);
    /* Cross-field rules of its record against the drive's configuration (mode: References.mode);
     * selected: the candidate configuration selects this law. */
    current_law_verdict_t (*check)(const drive_config_t *cfg, const void *record, uint8_t mode, int selected);
    /* A write to an entry of its record that is a command (reads back 0): apply = 0 before the write
     * (may refuse), apply = 1 after it (act; state is NULL when the law is not the one running).
     * CURRENT_LAW_NOT_COMMAND for a parameter. */
    current_law_verdict_t (*command)(void *state, const drive_config_t *cfg, void *record, uint8_t subindex,
                                     int running, int apply);
} current_law_t;

/* A registry row (generated: protocols/generated/current_law_table.c). */
typedef struct {
    uint8_t value;              /* Controller.controller */
    const current_law_t *law;   /* current_law_<value name> */
    uint16_t record_index;      /* its EDS record, 0: none */
    uint32_t record_bytes;      /* sizeof the record's generated struct */
    const void *record_default; /* the record with its EDS defaults */
} current_law_entry_t;

extern const current_law_entry_t current_law_table[];
extern const uint8_t current_law_count;

/* What the drive calls unconditionally is there, and the state fits (make LAW= checks the same at build
 * time, firmware_shim/law/law_check.c; the drive refuses to select a law that fails it). */
static inline int current_law_usable(const current_law_t *law)
{
    return law->configure != 0 && law->step != 0 && law->state_bytes <= CURRENT_LAW_STATE_BYTES;
}

/* A row installed at run time in place of the registry's row of the same value: a law prototyped in Python,
 * called through bench/direct/hil_pylaw.c in a direct run (docs/YOUR_CONTROLLER.md "Prototype in Python first");
 * NULL (the nodes and the MCU image never set it): none. */
extern const current_law_entry_t *current_law_override;

/* The row of a Controller.controller value, NULL for none (open loop, unknown, unusable). */
static inline const current_law_entry_t *current_law_find(uint8_t value)
{
    if (current_law_override != (const current_law_entry_t *)0 && current_law_override->value == value)
        return current_law_override;
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].value == value)
            return current_law_usable(current_law_table[i].law) ? &current_law_table[i]
                                                                : (const current_law_entry_t *)0;
    return (const current_law_entry_t *)0;
}

/* The stator-frame command of a dq command held over [k+1, k+2]: rotated by
 * the drive's angle advance (angle_advance_periods periods after the sample k:
 * 1.5, the EDS default, is the middle of the interval) at the electrical speed
 * of the sample. */
static inline void current_law_to_stator(const drive_config_t *cfg, const current_law_in_t *in, current_law_out_t *out)
{
    const float th_cmd = in->theta_e_rad + cfg->angle_advance_periods * in->omega_e_rad_s * cfg->Ts_s;
    dq_inv_park(out->v_d_V, out->v_q_V, cosf(th_cmd), sinf(th_cmd), &out->v_alpha_V, &out->v_beta_V);
}

/* Reserve a law's state in the drive: a compile-time error when it does not fit. */
#define CURRENT_LAW_STATE_FITS(state_t) \
    _Static_assert(sizeof(state_t) <= CURRENT_LAW_STATE_BYTES, #state_t " exceeds CURRENT_LAW_STATE_BYTES")

#endif

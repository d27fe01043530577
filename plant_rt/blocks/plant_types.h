/*
 * plant_types.h - the plant emulator's shared types: the configuration (plant_config_t), the state
 * (plant_state_t), the measurement, the energy account, the error codes and the enumerations of the EDS.
 * The blocks (plant_rt/blocks/), the machine models (plant_rt/models/) and the API (plant_rt/core/pmsm_plant.h)
 * all work on them; the conventions and the timing contract are pmsm_plant.h's.
 *
 * Plain C: no OS, no functions.
 */
#ifndef PLANT_TYPES_H
#define PLANT_TYPES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "od_plant_fields.h" /* the EDS's enumerations (protocols/gen_od.py) */
#include "plant_bridge.h"
#include "plant_fluxmap.h"
#include "plant_rng.h"

/* constants of the blocks */
#define PLANT_TWO_PI 6.283185307179586476925286766559005768
#define PLANT_SQRT3 1.732050807568877293527446341505872367

/* ---- error codes returned by plant_prepare ---------------------------- */
enum {
    PLANT_OK = 0,
    PLANT_ERR_NULL = -1,      /* NULL pointer */
    PLANT_ERR_NONFINITE = -2, /* NaN/Inf in a parameter */
    PLANT_ERR_TS = -3,        /* Ts_s <= 0 */
    PLANT_ERR_R = -4,         /* R_ohm < 0 */
    PLANT_ERR_L = -5,         /* Ld_H <= 0 or Lq_H <= 0 */
    PLANT_ERR_POLES = -6,     /* pole_pairs < 1 */
    PLANT_ERR_PSI = -7,       /* psi_Wb < 0 */
    PLANT_ERR_MECH = -8,      /* bad mode, J <= 0 in FREE, B < 0 */
    PLANT_ERR_VDC = -9,       /* Vdc <= 0 while modulation limit/dead time on */
    PLANT_ERR_DEADTIME = -10, /* t_dead < 0, t_dead >= Ts_pwm, I_sat < 0 */
    PLANT_ERR_SAT = -11,      /* saturation: I_sat <= 0 or Lq_inf not in (0, Lq] */
    PLANT_ERR_SENSOR = -12,   /* negative LSB/noise/full scale */
    PLANT_ERR_TRIP = -13,     /* I_trip < 0 */
    PLANT_ERR_RK4 = -14,      /* rk4_h_rel not in (0, 1] */
    PLANT_ERR_EXPM = -15,     /* matrix exponential failed (overflow) */
    PLANT_ERR_ENUM = -16,     /* modulation/hold/model enum out of range */
    PLANT_ERR_FLUXMAP = -17,  /* flux_map model without a usable map (plant_flux_map_check) */
    PLANT_ERR_THERMAL = -18,  /* thermal parameters negative, or a thermal model on the dq_linear model */
    PLANT_ERR_EXTERNAL = -19, /* fmu model without an external model (plant_external_t) */
    PLANT_ERR_REACTION = -20  /* trip_reaction out of range, or pulses_off without Vdc_V > 0 or on the fmu model */
};

/* the values of the EDS (ValueNames of Motor model.mech_mode, Inverter.mod_limit / hold_frame) */
typedef enum {
    PLANT_MECH_FREE = OD_PLANT_MECH_MODE_FREE,                  /* J domega/dt = Te - B omega - T_load */
    PLANT_MECH_LOCKED = OD_PLANT_MECH_MODE_LOCKED,              /* omega = 0, theta held */
    PLANT_MECH_IMPOSED_SPEED = OD_PLANT_MECH_MODE_IMPOSED_SPEED /* dynamometer holds omega_imposed_rad_s */
} plant_mech_mode_t;

/* the electrical model (ValueNames of Motor model.model) */
typedef enum {
    PLANT_MODEL_DQ_LINEAR = OD_PLANT_MODEL_DQ_LINEAR, /* R, Ld, Lq, psi (+ the q-axis saturation knob) */
    PLANT_MODEL_FLUX_MAP = OD_PLANT_MODEL_FLUX_MAP,   /* psi_d(id, iq), psi_q(id, iq) tables (plant_fluxmap.h) */
    PLANT_MODEL_EXTERNAL = OD_PLANT_MODEL_FMU         /* an external model (plant_external_t): an FMU */
} plant_model_t;

/* An external machine model (model == PLANT_MODEL_EXTERNAL), e.g. a co-simulation FMU (plant_rt/fmu/): it
 * replaces the machine block, electrical and mechanical; the inverter (modulation limit, dead time, trip) and
 * the sensors stay the plant's.  Its outputs in the stator frame: the currents (amplitude-invariant alpha-beta)
 * and the mechanical angle and speed. */
typedef struct {
    double i_alpha_A, i_beta_A;
    double theta_m_rad;
    double omega_m_rad_s;
} plant_external_out_t;

typedef struct {
    void *ctx;
    /* Advance the model by h_s from t_s with the applied stator-frame voltage held; its outputs at t_s + h_s.
     * Returns 0, or a non-zero error of the model (the plant then latches its trip and stops stepping it). */
    int (*step)(void *ctx, double t_s, double h_s, double v_alpha_V, double v_beta_V, plant_external_out_t *out);
    /* Back to the model's initial state; its outputs there.  Returns 0 or an error. */
    int (*restart)(void *ctx, plant_external_out_t *out);
} plant_external_t;

typedef enum {
    PLANT_MOD_NONE = OD_PLANT_MOD_LIMIT_NONE,         /* command applied as is */
    PLANT_MOD_SVPWM_HEX = OD_PLANT_MOD_LIMIT_HEXAGON, /* clip to hexagon, vertices 2/3 Vdc */
    PLANT_MOD_CIRCLE = OD_PLANT_MOD_LIMIT_CIRCLE      /* clip to circle of radius Vdc/sqrt(3) */
} plant_mod_limit_t;

typedef enum {
    PLANT_HOLD_STATOR = OD_PLANT_HOLD_FRAME_STATOR, /* real inverter: alpha-beta command constant */
    PLANT_HOLD_ROTOR = OD_PLANT_HOLD_FRAME_ROTOR    /* idealised model: dq command constant (for comparison) */
} plant_hold_frame_t;

/* What the bridge does once tripped (ValueNames of Inverter.trip_reaction; docs/YOUR_MOTOR.md) */
typedef enum {
    /* three switches of one side on: the terminals shorted, 0 V applied (with a turning rotor the short-circuit
     * current flows: id -> -psi w^2 Lq / (R^2 + w^2 Ld Lq), iq -> -psi w R / (R^2 + w^2 Ld Lq)) */
    PLANT_TRIP_ACTIVE_SHORT_CIRCUIT = OD_PLANT_TRIP_REACTION_ACTIVE_SHORT_CIRCUIT,
    /* all six off: the currents flow through the freewheeling diodes against the DC link until they reach zero;
     * the back-EMF drives a current only where its spread between phases exceeds Vdc (plant_bridge.h) */
    PLANT_TRIP_PULSES_OFF = OD_PLANT_TRIP_REACTION_PULSES_OFF
} plant_trip_reaction_t;

/* The machine models' own records (plant.eds "Model <name>", generated: OD_PLANT_MODEL_RECORDS), each as the EDS
 * has it (REAL32 values: what travels over SDO), by its OD member: c->params.x200A_model_harmonic.psi_5_Wb. */
#define PLANT_MODEL_PARAMS_MEMBER(name, type, record, index, fields) type record;
typedef struct {
    OD_PLANT_MODEL_RECORDS(PLANT_MODEL_PARAMS_MEMBER)
    uint8_t none_; /* a model without a record of its own: the struct is never empty */
} plant_model_params_t;
#undef PLANT_MODEL_PARAMS_MEMBER

/* ---- parameters ------------------------------------------------------- */
typedef struct {
    /* timing (every block) */
    double Ts_s; /* plant period = SYNC/current-loop period */

    /* motor (plant_machine) */
    double R_ohm; /* phase resistance */
    double Ld_H;
    double Lq_H;   /* unsaturated q inductance (Lq0) */
    double psi_Wb; /* magnet flux linkage (peak, per phase) */
    int32_t pole_pairs;

    /* q-axis saturation (off by default).  Flux-linkage model:
     *   psi_q(iq) = Lq_inf*iq + (Lq - Lq_inf)*I_sat*atan(iq/I_sat)
     *   L_inc(iq) = dpsi_q/diq = Lq_inf + (Lq - Lq_inf)/(1 + (iq/I_sat)^2)
     *   W_q(iq)   = Lq_inf*iq^2/2 + (Lq - Lq_inf)*I_sat^2/2*ln(1+(iq/I_sat)^2)
     * (W_q = integral of iq dpsi_q, so the model is energy consistent).  The
     * d axis stays linear.  Torque uses the flux form
     * Te = 1.5 p (psi_d iq - psi_q id), psi_d = Ld id + psi. */
    bool sat_enable;
    double sat_I_A;      /* current where L_inc drop is half of (Lq - Lq_inf) */
    double sat_Lq_inf_H; /* incremental inductance at |iq| -> inf */

    /* flux-map model (models/flux_map/flux_map.c): the states are the flux
     * linkages, the currents come from the inverted map, Te = 1.5 p (psi_d iq
     * - psi_q id); always on the RK4 path.  Ld_H, Lq_H, psi_Wb and the
     * saturation knob are not used by it.  The map belongs to the caller. */
    plant_model_t model;
    const plant_flux_map_t *flux_map;
    const plant_external_t *external; /* model == PLANT_MODEL_EXTERNAL: the caller's (an FMU) */
    plant_model_params_t params;      /* the models' own records (above) */
    /* winding temperature (flux_map model only): R = R_ohm (1 + R_alpha_per_K
     * (T - T_ref_degC)), C dT/dt = P_copper - (T - T_amb_degC) / R_th, one
     * exact first-order step a period with the period's mean copper loss.
     * thermal_C_J_per_K == 0: T stays at T_amb_degC. */
    double R_alpha_per_K;
    double T_ref_degC;
    double T_amb_degC;
    double thermal_R_K_per_W;
    double thermal_C_J_per_K;

    /* mechanics (plant_machine) */
    plant_mech_mode_t mech_mode;
    double J_kgm2;
    double B_Nm_per_rad_s;      /* viscous friction */
    double T_load_Nm;           /* constant load torque (opposes positive Te) */
    double omega_imposed_rad_s; /* mechanical speed in IMPOSED_SPEED mode */

    /* inverter (plant_inverter; hold_frame is applied by plant_machine) */
    double Vdc_V;
    plant_mod_limit_t mod_limit;
    /* dead time: per-phase voltage error
     *   dv_x = -V_dt * tanh(i_x / deadtime_I_sat_A),  V_dt = Vdc*t_dead/Ts_pwm
     * from the phase currents at the start of the period (deadtime_I_sat_A = 0
     * gives a hard sign()).  Off when t_dead_s == 0. */
    double t_dead_s;
    double Ts_pwm_s; /* PWM carrier period; 0 -> use Ts_s */
    double deadtime_I_sat_A;
    plant_hold_frame_t hold_frame;

    /* sensors (plant_sensors) */
    double adc_lsb_A; /* 0 = no quantization */
    double adc_offset_a_A;
    double adc_offset_b_A;
    double adc_noise_std_A;  /* 0 = no noise */
    double adc_full_scale_A; /* 0 = no clipping, else clip to +-FS */
    uint32_t encoder_lines;  /* 0 = ideal angle; else 4*lines counts/rev */
    uint64_t rng_seed;

    /* protection (plant_inverter): the trip latches (the bridge off from then
     * on, until plant_clear_trip: trip_reaction) when |i| of any phase exceeds
     * I_trip_A, and - even with the level off - on a non-finite voltage
     * command or phase current (a broken model state cannot be integrated
     * further).  The presets set a level derived from the motor (presets.c). */
    double I_trip_A; /* over-current level, peak phase A; 0 = off */
    /* what "off" means once tripped: 0 V (active short circuit, the default: a run is what it was before the
     * choice existed) or the switches off (the diodes conduct against Vdc_V; plant_bridge.h).  The external
     * model steps a period with one held voltage, which cannot follow the diodes: pulses_off is refused there. */
    plant_trip_reaction_t trip_reaction;

    /* numerics of the RK4 path (FREE mechanics or saturation; plant_machine) */
    double rk4_h_rel;          /* max h*lambda per sub-step (default 0.02) */
    uint32_t rk4_min_substeps; /* default 1 */
} plant_config_t;

/* ---- measurements (what the drive sees + truth for tracing) ----------- */
typedef struct {
    /* as measured */
    float i_a_A;           /* ADC phase a */
    float i_b_A;           /* ADC phase b */
    float theta_m_rad;     /* encoder (quantized, [0, 2pi)) */
    int32_t encoder_count; /* [0, 4*lines) or -1 when ideal */
    /* truth */
    double i_a_true_A, i_b_true_A, i_c_true_A;
    double i_alpha_A, i_beta_A;
    double id_A, iq_A;
    double theta_m_true_rad; /* [0, 2pi) */
    double theta_e_rad;      /* [0, 2pi) */
    double omega_m_rad_s;
    double torque_Nm;
    double t_s;
    uint64_t k;
    bool tripped;
} plant_meas_t;

/* ---- energy accounting (all since the last plant_energy_reset) -------- */
typedef struct {
    double in_J;       /* integral of 1.5 (vd id + vq iq) */
    double copper_J;   /* integral of 1.5 R (id^2 + iq^2) */
    double mech_J;     /* integral of Te * omega_m (air-gap -> shaft) */
    double friction_J; /* integral of B omega_m^2 (FREE mode only) */
    double load_J;     /* integral of T_load omega_m (FREE mode only) */
    double W_mag0_J;   /* stored magnetic energy at the reset */
    double W_kin0_J;   /* kinetic energy at the reset */
} plant_energy_t;

/* ---- runtime state ----------------------------------------------------- */
typedef struct {
    /* electrical, rotor frame (plant_machine) */
    double id_A, iq_A;
    /* mechanical (plant_machine) */
    double theta_m_rad; /* [0, 2pi) */
    int64_t revolutions;
    double omega_m_rad_s;
    double cos_e, sin_e; /* of theta_e = p*theta_m */
    /* time */
    uint64_t k;
    double t_s;
    /* inverter trace of the last step (plant_inverter) */
    double v_lim_alpha_V, v_lim_beta_V; /* command after modulation limit */
    double v_app_alpha_V, v_app_beta_V; /* actually applied (dead time, trip) */
    bool tripped;
    plant_bridge_t bridge; /* trip_reaction pulses_off: the diodes' conduction state (plant_bridge.h) */
    /* energy (plant_machine) */
    plant_energy_t energy;
    /* flux-map model (models/flux_map/flux_map.c): the flux linkages (the
     * states; id_A/iq_A above follow from them), the magnetic energy as the
     * integral of i . dpsi, the incremental inductances at the present
     * currents, the winding's temperature and resistance */
    double psi_d_Wb, psi_q_Wb;
    bool psi_stale; /* plant_set_currents: the fluxes follow at the next step */
    double W_mag_J;
    double cell_min_A;                    /* the map's narrowest cell (the sub-steps' bound on the cells crossed) */
    const plant_flux_map_t *prepared_map; /* the map the fluxes were last taken from */
    double Ldd_H, Ldq_H, Lqd_H, Lqq_H;
    double T_winding_degC, R_winding_ohm;
    uint32_t outside_map_periods; /* periods that ended with the currents outside the map's grid */
    uint32_t newton_failures;     /* inversions that did not converge (should stay 0) */
    int32_t newton_evals_max;     /* the most map evaluations one inversion took */
    /* external model (models/external/external.c): its last error (0: none; the model is then no longer stepped) */
    int32_t external_error;
    double external_t0_s; /* the plant's time at the model's (re)start: the model's time is t_s minus this */
    /* sensors: ADC noise (plant_sensors) */
    plant_rng_t rng;

    /* ---- discretization cache (written by plant_prepare; plant_machine
     * but for Vdt_V, plant_inverter) ---- */
    int status;                            /* result of the last plant_prepare */
    const struct plant_model_desc *model;  /* the model plant_prepare chose (plant_model.h); NULL: none */
    bool exact;                            /* exact matrix-exponential path */
    double phi[2][5];                      /* rows id, iq of expm(A Ts) */
    double q_in[15], q_cu[15], q_mech[15]; /* packed upper x'Mx weights */
    double rot_c, rot_s;                   /* cos/sin(w Ts) */
    double dtheta_m;                       /* omega_m * Ts */
    uint32_t resync;                       /* steps since cos/sin resync */
    double Vdt_V;                          /* dead-time error magnitude */
    double lam_base;                       /* R/Lmin (+ electromech. freq in FREE) */
    double Lmin_H;
    uint32_t last_substeps; /* RK4 sub-steps used in the last period */
} plant_state_t;

#endif

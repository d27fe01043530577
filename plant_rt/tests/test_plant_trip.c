/*
 * Over-current trip: You 2019 motor, locked at theta = 0 (phase a on d),
 * v_alpha = 20 V step, I_trip = 5 A.  Expected trip period from the RL
 * closed form: first k with (V/R)(1 - exp(-k Ts R/Ld)) > I_trip.  After the
 * trip the applied voltage is 0 and the current decays by exp(-Ts R/Ld) per
 * period; clearing while |i| > I_trip re-trips before any voltage is applied;
 * clearing below the threshold lets the voltage through again.
 * A second case trips on phase b (rotor at theta_e = 120 deg).
 */
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_LOCKED;
    c.I_trip_A = 5.0;
    const double V = 20.0, R = c.R_ohm, L = c.Ld_H, a = exp(-c.Ts_s * R / L);
    int kexp = 0;
    for (int k = 1; k < 100000; ++k) {
        if (V / R * (1.0 - exp(-k * c.Ts_s * R / L)) > c.I_trip_A) {
            kexp = k;
            break;
        }
    }
    plant_state_t s;
    plant_init(&s, &c);
    int ktrip = -1;
    for (int k = 1; k <= 2000 && ktrip < 0; ++k) {
        plant_step(&s, &c, V, 0.0);
        if (s.tripped) {
            ktrip = k;
        }
    }
    plant_meas_t m;
    plant_sample(&s, &c, &m);
    printf("trip at period %d (expected %d), i_a = %.6f A, meas.tripped = %d\n", ktrip, kexp, s.id_A,
           (int)m.tripped);
    CHECK(ktrip == kexp, "trip instant");
    CHECK(m.tripped, "trip flag in measurement");
    /* clear above threshold -> re-trips at the start of the next period,
     * before any voltage is applied */
    CHECK(s.id_A > c.I_trip_A, "still above the threshold");
    const double i_clear = s.id_A;
    plant_clear_trip(&s);
    CHECK(!s.tripped, "cleared");
    plant_step(&s, &c, V, 0.0);
    printf("clear at %.4f A (> I_trip), one step: tripped again = %d, applied %.1f V\n", i_clear,
           (int)s.tripped, s.v_app_alpha_V);
    CHECK(s.tripped && s.v_app_alpha_V == 0.0, "re-trip when cleared above threshold");
    /* zero voltage, exponential decay */
    double i0 = s.id_A, emax = 0.0;
    for (int k = 1; k <= 50; ++k) {
        plant_step(&s, &c, V, 0.0);
        CHECK(s.v_app_alpha_V == 0.0 && s.v_app_beta_V == 0.0, "zero voltage while tripped");
        emax = fmax(emax, fabs(s.id_A - i0 * pow(a, k)));
    }
    printf("while tripped: current decays as exp(-t R/Ld), max err %.3e A, i = %.4f A after 50 more periods\n",
           emax, s.id_A);
    CHECK(emax < 1e-12, "decay");
    while (s.id_A > 1.0) {
        plant_step(&s, &c, V, 0.0);
    }
    plant_clear_trip(&s);
    plant_step(&s, &c, V, 0.0);
    printf("clear at %.3f A: tripped = %d, applied %.1f V\n", s.id_A, (int)s.tripped, s.v_app_alpha_V);
    CHECK(!s.tripped && s.v_app_alpha_V == V, "voltage back after clear");

    /* trip on phase b: theta_e = 120 deg -> d axis on phase b */
    {
        plant_state_t s2;
        plant_init(&s2, &c);
        plant_set_mech(&s2, &c, (2.0 * (double)T_PI / 3.0) / 5.0, 0.0);
        const double vb_a = V * cos(2.0 * (double)T_PI / 3.0), vb_b = V * sin(2.0 * (double)T_PI / 3.0);
        int kt = -1;
        for (int k = 1; k <= 2000 && kt < 0; ++k) {
            plant_step(&s2, &c, vb_a, vb_b);
            if (s2.tripped) {
                kt = k;
            }
        }
        plant_meas_t m2;
        plant_sample(&s2, &c, &m2);
        printf("phase-b case: trip at period %d (expected %d), i_b = %.4f A, i_a = %.4f A\n", kt, kexp,
               m2.i_b_true_A, m2.i_a_true_A);
        CHECK(kt == kexp, "phase b trip instant");
    }
    /* trip disabled */
    {
        plant_config_t c0 = c;
        c0.I_trip_A = 0.0;
        plant_state_t s3;
        plant_init(&s3, &c0);
        for (int k = 0; k < 5000; ++k) {
            plant_step(&s3, &c0, V, 0.0);
        }
        printf("I_trip = 0: i = %.3f A, tripped = %d\n", s3.id_A, (int)s3.tripped);
        CHECK(!s3.tripped && s3.id_A > 10.0, "no trip when disabled");
    }
    return test_finish("test_plant_trip");
}

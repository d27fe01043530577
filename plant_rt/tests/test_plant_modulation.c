/*
 * Modulation limits (Vdc = 300 V): the SVPWM hexagon has vertices at
 * 2/3 Vdc = 200 V on the phase axes (0, 60, ... deg) and inscribed circle
 * Vdc/sqrt(3) = 173.2 V; the CIRCLE limit is that inscribed circle.
 * Boundary of the hexagon at angle phi (independent trig formula):
 *   r(phi) = (Vdc/sqrt 3) / cos(((phi mod 60deg) - 30deg)).
 * Over-range commands are scaled toward the origin (angle preserved).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t c;
    plant_config_defaults(&c);
    c.Vdc_V = 300.0;
    const double rc = c.Vdc_V / sqrt(3.0);
    double eh = 0.0, ec = 0.0, eang = 0.0, rmin = 1e9, rmax = 0.0;
    for (int k = 0; k < 3600; ++k) {
        const double phi = 2.0 * (double)T_PI * k / 3600.0;
        const double big = 1000.0;
        double va = big * cos(phi), vb = big * sin(phi);
        c.mod_limit = PLANT_MOD_SVPWM_HEX;
        plant_modulation_limit(&c, &va, &vb);
        const double m60 = fmod(phi, (double)T_PI / 3.0) - (double)T_PI / 6.0;
        const double rh = rc / cos(m60);
        const double r = hypot(va, vb);
        eh = fmax(eh, fabs(r - rh));
        rmin = fmin(rmin, r);
        rmax = fmax(rmax, r);
        eang = fmax(eang, fabs(va * sin(phi) - vb * cos(phi)));
        va = big * cos(phi);
        vb = big * sin(phi);
        c.mod_limit = PLANT_MOD_CIRCLE;
        plant_modulation_limit(&c, &va, &vb);
        ec = fmax(ec, fabs(hypot(va, vb) - rc));
        eang = fmax(eang, fabs(va * sin(phi) - vb * cos(phi)));
    }
    printf("hexagon: |v| from %.4f V (expect %.4f) to %.4f V (expect %.4f), max boundary err %.3e V\n", rmin, rc, rmax,
           2.0 * c.Vdc_V / 3.0, eh);
    printf("circle: max radius err %.3e V; max angle deviation (cross product) %.3e V\n", ec, eang);
    CHECK(eh < 1e-9, "hexagon boundary");
    CHECK(ec < 1e-9, "circle boundary");
    CHECK(eang < 1e-9, "direction preserved");
    CHECK(fabs(rmax - 200.0) < 1e-9 && fabs(rmin - rc) < 1e-6, "hexagon extremes");

    /* inside points are untouched; 190 V on the a axis: inside hex, outside circle */
    struct {
        double va, vb;
        int mode;
        double ea, eb;
    } cases[] = {
        {150.0, -20.0, PLANT_MOD_SVPWM_HEX, 150.0, -20.0},
        {150.0, -20.0, PLANT_MOD_CIRCLE, 150.0, -20.0},
        {190.0, 0.0, PLANT_MOD_SVPWM_HEX, 190.0, 0.0},
        {190.0, 0.0, PLANT_MOD_CIRCLE, 173.20508075688772, 0.0},
        {0.0, 190.0, PLANT_MOD_SVPWM_HEX, 0.0, 173.20508075688772},
        {400.0, 0.0, PLANT_MOD_NONE, 400.0, 0.0},
    };
    for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); ++i) {
        c.mod_limit = (plant_mod_limit_t)cases[i].mode;
        plant_state_t s;
        plant_init(&s, &c);
        CHECK(s.status == 0, "prepare");
        plant_step(&s, &c, cases[i].va, cases[i].vb);
        printf("mode %d: command (%.1f, %.1f) -> applied (%.6f, %.6f)\n", cases[i].mode, cases[i].va, cases[i].vb,
               s.v_app_alpha_V, s.v_app_beta_V);
        CHECK(fabs(s.v_app_alpha_V - cases[i].ea) < 1e-9 && fabs(s.v_app_beta_V - cases[i].eb) < 1e-9, "case %zu", i);
    }
    return check_finish("test_plant_modulation");
}

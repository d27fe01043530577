/* test_pi_current.c - PI baseline: small step tracking and a large
 * voltage-limited step without integrator windup. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "drive_core.h"
#include "drive_plant.h"

static void run(double ref, double *overshoot, int *t98, int *nlim, double *final, double *integ_max)
{
    static drive_t drv;
    drive_config_t cfg;
    drive_plant_t pl;
    drive_plant_init(&pl, "you2019");
    drive_default_config(&cfg);
    cfg.controller = (uint8_t)OD_DRIVE_CONTROLLER_PI;
    drive_init(&drv, &cfg);
    double imax = 0;
    *t98 = -1;
    *nlim = 0;
    *integ_max = 0;
    for (int k = 0; k < 3000; ++k) {
        drive_meas_t m;
        drive_cmd_t c;
        drive_plant_measure(&pl, &m);
        drv.sp.iq_ref_A = k >= 10 ? (float)ref : 0.0f;
        drive_current_step(&drv, &m, &c);
        const double iq = (double)drv.st.i_q_A;
        if (iq > imax) imax = iq;
        if (*t98 < 0 && iq >= 0.98 * ref) *t98 = k - 10;
        *nlim += drv.st.out.v_limited;
        if (fabs((double)YOU2019_OF(drv)->pi.integ_q_V) > *integ_max)
            *integ_max = fabs((double)YOU2019_OF(drv)->pi.integ_q_V);
        *final = iq;
        drive_plant_advance(&pl, &c);
    }
    *overshoot = (imax - ref) / ref;
}

int main(void)
{
    double os, fin, imx;
    int t98, nlim;
    run(1.0, &os, &t98, &nlim, &fin, &imx);
    const double tau_periods = 1.0 / (2 * 3.14159265 * 1000.0 * 55e-6);
    printf("[PI 1 kHz, 0->1A] overshoot=%.2f%% periods to 98%%=%d (first-order ideal %.1f + delay)"
           " final=%.5f limited=%d\n",
           100 * os, t98, 3.9 * tau_periods, fin, nlim);
    CHECK(os < 0.10, "overshoot");
    CHECK(fabs(fin - 1) < 1e-4, "steady state");
    CHECK(nlim == 0, "should not saturate");
    run(20.0, &os, &t98, &nlim, &fin, &imx);
    printf("[PI 1 kHz, 0->20A, Vmax 139V] overshoot=%.2f%% periods to 98%%=%d limited=%d "
           "max|integ|=%.1f V (steady R*i=%.1f V) final=%.4f\n",
           100 * os, t98, nlim, imx, 1.4 * 20, fin);
    CHECK(nlim > 0, "20 A step should saturate");
    CHECK(os < 0.12, "windup overshoot %.3f", os);
    CHECK(fabs(fin - 20) < 1e-3, "steady state");
    return check_finish("test_pi_current");
}

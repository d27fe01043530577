/* plant_fmu.c - a co-simulation FMU as the plant's external machine model (plant_fmu.h): the spec of its 0x2009 text
 * (plant_fmu_text.c), the binary loaded with dlopen, FMI 2.0 or 3.0 co-simulation through the standard's C interface as
 * plant_fmi_api.h declares it (no external FMI header).
 * Host glue (dlfcn, stdio): not part of the portable core.  One model a process (a plant node is one process;
 * the direct mode's library holds one plant). */
#include "plant_fmu.h"

#include "co_od.h"
#include "plant_fmi_api.h"

#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SQRT3 1.732050807568877293527446341505872367

/* ------------------------------------------------------------------ the model */

static struct {
    void *dl;
    plant_fmu_spec_t spec;
    int loaded;
    double theta_m; /* the model's last angle (dq inputs) */
    /* FMI 2 */
    plant_fmi2_component_t c2;
    plant_fmi2_callbacks_t cb2;
    plant_fmi2_instantiate_fn inst2;
    plant_fmi2_free_instance_fn free2;
    plant_fmi2_setup_experiment_fn setup2;
    plant_fmi2_instance_fn enter2;
    plant_fmi2_instance_fn exit2;
    plant_fmi2_set_real_fn set2;
    plant_fmi2_get_real_fn get2;
    plant_fmi2_do_step_fn step2;
    plant_fmi2_instance_fn term2;
    plant_fmi2_instance_fn reset2;
    /* FMI 3 */
    plant_fmi3_instance_t c3;
    plant_fmi3_instantiate_cs_fn inst3;
    plant_fmi3_free_instance_fn free3;
    plant_fmi3_enter_init_fn enter3;
    plant_fmi3_instance_fn exit3;
    plant_fmi3_set_float64_fn set3;
    plant_fmi3_get_float64_fn get3;
    plant_fmi3_do_step_fn step3;
    plant_fmi3_instance_fn term3;
    plant_fmi3_instance_fn reset3;
    plant_external_t ext;
} F;

static void fmu_log2(plant_fmi2_environment_t env, plant_fmi2_string_t name, plant_fmi2_status_t status,
                     plant_fmi2_string_t category, plant_fmi2_string_t message, ...)
{
    (void)env;
    if (status < PLANT_FMI2_WARNING) return;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "plant: FMU %s [%s]: ", name ? name : "?", category ? category : "");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void fmu_log3(plant_fmi3_environment_t env, plant_fmi3_status_t status, plant_fmi3_string_t category,
                     plant_fmi3_string_t message)
{
    (void)env;
    if (status < PLANT_FMI3_WARNING) return;
    fprintf(stderr, "plant: FMU [%s]: %s\n", category ? category : "", message ? message : "");
}

static int set_reals(const uint32_t *vr, const double *v, size_t n)
{
    if (F.spec.fmi == 2) return F.set2(F.c2, vr, n, v) > PLANT_FMI2_WARNING ? -1 : 0;
    return F.set3(F.c3, vr, n, v, n) > PLANT_FMI3_WARNING ? -1 : 0;
}

static int get_reals(const uint32_t *vr, double *v, size_t n)
{
    if (F.spec.fmi == 2) return F.get2(F.c2, vr, n, v) > PLANT_FMI2_WARNING ? -1 : 0;
    return F.get3(F.c3, vr, n, v, n) > PLANT_FMI3_WARNING ? -1 : 0;
}

/* The model's outputs in the plant's terms (stator frame, mechanical angle and speed). */
static int outputs(plant_external_out_t *out)
{
    double v[2], th, w = 0.0;
    if (get_reals(F.spec.out_vr, v, 2) || get_reals(&F.spec.theta_vr, &th, 1)) return -2;
    if (F.spec.has_omega && get_reals(&F.spec.omega_vr, &w, 1)) return -2;
    F.theta_m = th;
    const double te = (double)F.spec.pole_pairs * th, ce = cos(te), se = sin(te);
    switch (F.spec.outputs) {
    case PLANT_FMU_PHASE: /* amplitude-invariant Clarke of a balanced set */
        out->i_alpha_A = v[0];
        out->i_beta_A = (v[0] + 2.0 * v[1]) / SQRT3;
        break;
    case PLANT_FMU_DQ:
        out->i_alpha_A = ce * v[0] - se * v[1];
        out->i_beta_A = se * v[0] + ce * v[1];
        break;
    default:
        out->i_alpha_A = v[0];
        out->i_beta_A = v[1];
        break;
    }
    out->theta_m_rad = th;
    out->omega_m_rad_s = w;
    return 0;
}

static int do_step(double t, double h)
{
    if (F.spec.fmi == 2) {
        const plant_fmi2_status_t st = F.step2(F.c2, t, h, PLANT_FMI2_TRUE);
        return st > PLANT_FMI2_WARNING ? (int)st : 0;
    }
    bool event = false, terminate = false, early = false;
    double last = t;
    const plant_fmi3_status_t st = F.step3(F.c3, t, h, true, &event, &terminate, &early, &last);
    if (st > PLANT_FMI3_WARNING) return (int)st;
    return terminate ? 6 : 0;
}

static int ext_step(void *ctx, double t_s, double h_s, double va, double vb, plant_external_out_t *out)
{
    (void)ctx;
    const double h = h_s / (double)F.spec.substeps;
    for (uint32_t k = 0; k < F.spec.substeps; ++k) {
        double v[2] = {va, vb};
        if (F.spec.inputs == PLANT_FMU_DQ) { /* at the model's present angle */
            const double te = (double)F.spec.pole_pairs * F.theta_m, ce = cos(te), se = sin(te);
            v[0] = ce * va + se * vb;
            v[1] = -se * va + ce * vb;
        }
        if (set_reals(F.spec.in_vr, v, 2)) return -3;
        const int st = do_step(t_s + (double)k * h, h);
        if (st != 0) return st;
        if (F.spec.inputs == PLANT_FMU_DQ && k + 1u < F.spec.substeps) {
            double th;
            if (get_reals(&F.spec.theta_vr, &th, 1)) return -2;
            F.theta_m = th;
        }
    }
    return outputs(out);
}

/* Parameters, then initialization at t = 0. */
static int initialize(char *err, size_t n)
{
    for (uint32_t i = 0; i < F.spec.n_params; ++i) {
        if (set_reals(&F.spec.param_vr[i], &F.spec.param_value[i], 1)) {
            plant_fmu_say(err, n, "the FMU refused parameter value reference %u = %g", F.spec.param_vr[i],
                          F.spec.param_value[i]);
            return -1;
        }
    }
    int bad;
    if (F.spec.fmi == 2) {
        bad = F.setup2(F.c2, PLANT_FMI2_FALSE, 0.0, 0.0, PLANT_FMI2_FALSE, 0.0) > PLANT_FMI2_WARNING ||
              F.enter2(F.c2) > PLANT_FMI2_WARNING || F.exit2(F.c2) > PLANT_FMI2_WARNING;
    } else {
        bad = F.enter3(F.c3, false, 0.0, 0.0, false, 0.0) > PLANT_FMI3_WARNING || F.exit3(F.c3) > PLANT_FMI3_WARNING;
    }
    if (bad) plant_fmu_say(err, n, "the FMU's initialization failed");
    return bad ? -1 : 0;
}

static int ext_restart(void *ctx, plant_external_out_t *out)
{
    (void)ctx;
    const int bad = F.spec.fmi == 2 ? F.reset2(F.c2) > PLANT_FMI2_WARNING : F.reset3(F.c3) > PLANT_FMI3_WARNING;
    if (bad || initialize(NULL, 0) != 0) return -4;
    return outputs(out);
}

void plant_fmu_unload(void)
{
    if (!F.loaded) return;
    if (F.spec.fmi == 2) {
        (void)F.term2(F.c2);
        F.free2(F.c2);
    } else {
        (void)F.term3(F.c3);
        F.free3(F.c3);
    }
    dlclose(F.dl);
    memset(&F, 0, sizeof F);
}

static void *sym(const char *name, char *err, size_t n, int *missing)
{
    void *p = dlsym(F.dl, name);
    if (p == NULL && !*missing) {
        plant_fmu_say(err, n, "%s has no function %s", F.spec.library, name);
        *missing = 1;
    }
    return p;
}

int plant_fmu_load(const plant_fmu_spec_t *spec, const plant_external_t **ext, char *err, size_t err_len)
{
    plant_fmu_unload();
    F.spec = *spec;
    F.dl = dlopen(spec->library, RTLD_NOW | RTLD_LOCAL);
    if (F.dl == NULL) {
        plant_fmu_say(err, err_len, "cannot load %s: %s", spec->library, dlerror());
        memset(&F, 0, sizeof F);
        return -1;
    }
    int missing = 0;
    if (spec->fmi == 2) {
        F.inst2 = (plant_fmi2_instantiate_fn)sym("fmi2Instantiate", err, err_len, &missing);
        F.free2 = (plant_fmi2_free_instance_fn)sym("fmi2FreeInstance", err, err_len, &missing);
        F.setup2 = (plant_fmi2_setup_experiment_fn)sym("fmi2SetupExperiment", err, err_len, &missing);
        F.enter2 = (plant_fmi2_instance_fn)sym("fmi2EnterInitializationMode", err, err_len, &missing);
        F.exit2 = (plant_fmi2_instance_fn)sym("fmi2ExitInitializationMode", err, err_len, &missing);
        F.set2 = (plant_fmi2_set_real_fn)sym("fmi2SetReal", err, err_len, &missing);
        F.get2 = (plant_fmi2_get_real_fn)sym("fmi2GetReal", err, err_len, &missing);
        F.step2 = (plant_fmi2_do_step_fn)sym("fmi2DoStep", err, err_len, &missing);
        F.term2 = (plant_fmi2_instance_fn)sym("fmi2Terminate", err, err_len, &missing);
        F.reset2 = (plant_fmi2_instance_fn)sym("fmi2Reset", err, err_len, &missing);
    } else {
        F.inst3 = (plant_fmi3_instantiate_cs_fn)sym("fmi3InstantiateCoSimulation", err, err_len, &missing);
        F.free3 = (plant_fmi3_free_instance_fn)sym("fmi3FreeInstance", err, err_len, &missing);
        F.enter3 = (plant_fmi3_enter_init_fn)sym("fmi3EnterInitializationMode", err, err_len, &missing);
        F.exit3 = (plant_fmi3_instance_fn)sym("fmi3ExitInitializationMode", err, err_len, &missing);
        F.set3 = (plant_fmi3_set_float64_fn)sym("fmi3SetFloat64", err, err_len, &missing);
        F.get3 = (plant_fmi3_get_float64_fn)sym("fmi3GetFloat64", err, err_len, &missing);
        F.step3 = (plant_fmi3_do_step_fn)sym("fmi3DoStep", err, err_len, &missing);
        F.term3 = (plant_fmi3_instance_fn)sym("fmi3Terminate", err, err_len, &missing);
        F.reset3 = (plant_fmi3_instance_fn)sym("fmi3Reset", err, err_len, &missing);
    }
    if (missing) {
        dlclose(F.dl);
        memset(&F, 0, sizeof F);
        return -1;
    }
    if (spec->fmi == 2) {
        F.cb2 = (plant_fmi2_callbacks_t){fmu_log2, calloc, free, NULL, NULL};
        F.c2 = F.inst2(spec->identifier, PLANT_FMI2_CO_SIMULATION, spec->token, spec->resources, &F.cb2,
                       PLANT_FMI2_FALSE, PLANT_FMI2_FALSE);
    } else {
        F.c3 = F.inst3(spec->identifier, spec->token, spec->resources, false, false, false, false, NULL, 0, NULL,
                       fmu_log3, NULL);
    }
    if ((spec->fmi == 2 && F.c2 == NULL) || (spec->fmi == 3 && F.c3 == NULL)) {
        plant_fmu_say(err, err_len, "%s: the FMU's instantiation failed (token %s)", spec->library, spec->token);
        dlclose(F.dl);
        memset(&F, 0, sizeof F);
        return -1;
    }
    F.loaded = 1;
    if (initialize(err, err_len) != 0) {
        plant_fmu_unload();
        return -1;
    }
    plant_external_out_t out;
    if (outputs(&out) != 0) {
        plant_fmu_say(err, err_len, "%s: the FMU's outputs cannot be read", spec->library);
        plant_fmu_unload();
        return -1;
    }
    F.ext = (plant_external_t){NULL, ext_step, ext_restart};
    *ext = &F.ext;
    return 0;
}

uint32_t plant_fmu_load_text(const uint8_t *text, uint32_t len, const plant_external_t **ext)
{
    static plant_fmu_spec_t spec; /* not on the stack: ~2.5 kB, and a load is not in the period's path */
    char err[1400];
    if (plant_fmu_parse((const char *)text, len, &spec, err, sizeof err) != 0 ||
        plant_fmu_load(&spec, ext, err, sizeof err) != 0) {
        fprintf(stderr, "plant: 0x2009 FMU refused: %s\n", err);
        return CO_ABORT_INVALID_VALUE;
    }
    return 0u;
}

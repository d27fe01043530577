/* plant_fmu.c - a co-simulation FMU as the plant's external machine model (plant_fmu.h): the 0x2009 text parsed,
 * the binary loaded with dlopen, FMI 2.0 or 3.0 co-simulation through the standard's C interface as
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

static void say(char *err, size_t n, const char *fmt, ...)
{
    if (err == NULL || n == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, n, fmt, ap);
    va_end(ap);
}

/* ------------------------------------------------------------------ the 0x2009 text */

static int frame_of(const char *v, plant_fmu_frame_t *f, int phase_ok)
{
    if (strcmp(v, "alpha_beta") == 0) {
        *f = PLANT_FMU_AB;
    } else if (strcmp(v, "dq") == 0) {
        *f = PLANT_FMU_DQ;
    } else if (phase_ok && strcmp(v, "phase") == 0) {
        *f = PLANT_FMU_PHASE;
    } else {
        return -1;
    }
    return 0;
}

static int number(const char *v, double *x)
{
    char *end = NULL;
    *x = strtod(v, &end);
    return (end != v && *end == '\0' && isfinite(*x)) ? 0 : -1;
}

static int vref(const char *v, uint32_t *r)
{
    char *end = NULL;
    const unsigned long x = strtoul(v, &end, 10);
    if (end == v || *end != '\0' || x > 0xFFFFFFFFul) return -1;
    *r = (uint32_t)x;
    return 0;
}

static int copy(char *dst, size_t n, const char *v)
{
    if (strlen(v) >= n) return -1;
    strcpy(dst, v);
    return 0;
}

/* One "key value" line into the spec; 0 or -1. */
static int take(plant_fmu_spec_t *s, const char *key, char *val, char *err, size_t n)
{
    double x;
    int bad = 0;
    if (strcmp(key, "fmi") == 0) {
        bad = number(val, &x) || !(x == 2.0 || x == 3.0);
        if (!bad) s->fmi = (int)x;
    } else if (strcmp(key, "library") == 0) {
        bad = copy(s->library, sizeof s->library, val);
    } else if (strcmp(key, "identifier") == 0) {
        bad = copy(s->identifier, sizeof s->identifier, val);
    } else if (strcmp(key, "token") == 0) {
        bad = copy(s->token, sizeof s->token, val);
    } else if (strcmp(key, "resources") == 0) {
        bad = copy(s->resources, sizeof s->resources, val);
    } else if (strcmp(key, "inputs") == 0) {
        bad = frame_of(val, &s->inputs, 0);
    } else if (strcmp(key, "outputs") == 0) {
        bad = frame_of(val, &s->outputs, 1);
    } else if (strcmp(key, "in0") == 0 || strcmp(key, "in1") == 0) {
        bad = vref(val, &s->in_vr[key[2] - '0']);
    } else if (strcmp(key, "out0") == 0 || strcmp(key, "out1") == 0) {
        bad = vref(val, &s->out_vr[key[3] - '0']);
    } else if (strcmp(key, "theta") == 0) {
        bad = vref(val, &s->theta_vr);
    } else if (strcmp(key, "omega") == 0) {
        bad = vref(val, &s->omega_vr);
        s->has_omega = 1;
    } else if (strcmp(key, "pole_pairs") == 0) {
        bad = number(val, &x) || x < 1.0 || x > 1000.0 || x != floor(x);
        if (!bad) s->pole_pairs = (int)x;
    } else if (strcmp(key, "substeps") == 0) {
        bad = number(val, &x) || x < 1.0 || x > 10000.0 || x != floor(x);
        if (!bad) s->substeps = (uint32_t)x;
    } else if (strcmp(key, "param") == 0) {
        char *sp = strchr(val, ' ');
        if (sp == NULL || s->n_params >= PLANT_FMU_MAX_PARAMS) {
            bad = 1;
        } else {
            *sp = '\0';
            bad = vref(val, &s->param_vr[s->n_params]) || number(sp + 1, &s->param_value[s->n_params]);
            ++s->n_params;
        }
    } else {
        say(err, n, "0x2009 FMU: unknown key %s", key);
        return -1;
    }
    if (bad) say(err, n, "0x2009 FMU: bad value for %s: %s", key, val);
    return bad ? -1 : 0;
}

int plant_fmu_parse(const char *text, size_t len, plant_fmu_spec_t *spec, char *err, size_t err_len)
{
    memset(spec, 0, sizeof *spec);
    spec->pole_pairs = 1;
    spec->substeps = 1u;
    char line[1200];
    size_t i = 0;
    unsigned seen = 0u; /* fmi, library, token, in0, in1, out0, out1, theta */
    while (i < len) {
        size_t j = i;
        while (j < len && text[j] != '\n') ++j;
        const size_t n = j - i;
        if (n >= sizeof line) {
            say(err, err_len, "0x2009 FMU: a line longer than %zu characters", sizeof line - 1);
            return -1;
        }
        memcpy(line, text + i, n);
        line[n] = '\0';
        i = j + 1;
        if (n == 0) continue;
        char *sp = strchr(line, ' ');
        if (sp == NULL) {
            say(err, err_len, "0x2009 FMU: line without a value: %s", line);
            return -1;
        }
        *sp = '\0';
        if (take(spec, line, sp + 1, err, err_len) != 0) return -1;
        const char *keys[] = {"fmi", "library", "token", "in0", "in1", "out0", "out1", "theta"};
        for (unsigned k = 0; k < 8u; ++k)
            if (strcmp(line, keys[k]) == 0) seen |= 1u << k;
    }
    if (seen != 0xFFu) {
        say(err, err_len, "0x2009 FMU: fmi, library, token, in0, in1, out0, out1 and theta are required");
        return -1;
    }
    return 0;
}

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
            say(err, n, "the FMU refused parameter value reference %u = %g", F.spec.param_vr[i], F.spec.param_value[i]);
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
    if (bad) say(err, n, "the FMU's initialization failed");
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
        say(err, n, "%s has no function %s", F.spec.library, name);
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
        say(err, err_len, "cannot load %s: %s", spec->library, dlerror());
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
        say(err, err_len, "%s: the FMU's instantiation failed (token %s)", spec->library, spec->token);
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
        say(err, err_len, "%s: the FMU's outputs cannot be read", spec->library);
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

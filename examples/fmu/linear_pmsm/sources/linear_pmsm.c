/* linear_pmsm.c - the bench's linear PMSM as an FMI 2.0 co-simulation FMU (examples/fmu/linear_pmsm, the example of
 * docs/YOUR_MOTOR.md): the plant's model of plant_rt/core/pmsm_plant.h, written again here as a user's FMU would
 * be, for the FMU plant to be compared with the built-in one.
 *
 * Rotor dq frame, d on the magnet, motor convention (You 2019 Eq. 1):
 *     Ld did/dt = vd - R id + w Lq iq,   Lq diq/dt = vq - R iq - w Ld id - w psi,   w = p omega_m
 * The input is the stator-frame voltage, held over a communication step (so it rotates in the rotor frame);
 * the rotor turns at omega_imposed (0: locked).  Classical RK4 with `substeps` steps a communication step.
 * Outputs: the phase currents a and b (amplitude-invariant inverse Clarke), the mechanical angle and speed.
 * A test's fault: doStep returns fmi2Error once the communication point reaches fail_at (> 0). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

enum { V_ALPHA, V_BETA, I_A, I_B, THETA_M, OMEGA_M, N_IO };
enum { P_R = 10, P_LD, P_LQ, P_PSI, P_POLES, P_OMEGA, P_SUBSTEPS, P_FAIL_AT, P_END };

typedef struct {
    double io[N_IO];
    double par[P_END - P_R];
    double id, iq, theta_m;
    int failed;
} model_t;

static const double k_defaults[P_END - P_R] = {1.4, 4.46e-3, 4.54e-3, 0.042, 5.0, 0.0, 20.0, 0.0};

static double *ref(model_t *m, fmi2ValueReference vr)
{
    if (vr < N_IO) return &m->io[vr];
    if (vr >= P_R && vr < P_END) return &m->par[vr - P_R];
    return NULL;
}

static void outputs(model_t *m)
{
    const double te = m->par[P_POLES - P_R] * m->theta_m, c = cos(te), s = sin(te);
    const double ial = c * m->id - s * m->iq, ibe = s * m->id + c * m->iq;
    m->io[I_A] = ial;
    m->io[I_B] = -0.5 * ial + 0.5 * sqrt(3.0) * ibe;
    m->io[THETA_M] = m->theta_m;
    m->io[OMEGA_M] = m->par[P_OMEGA - P_R];
}

static void reset_state(model_t *m)
{
    m->id = m->iq = m->theta_m = 0.0;
    m->failed = 0;
    outputs(m);
}

/* d/dt (id, iq) at the angle th_m */
static void deriv(const model_t *m, double th_m, double id, double iq, double *did, double *diq)
{
    const double R = m->par[0], Ld = m->par[1], Lq = m->par[2], psi = m->par[3], p = m->par[4];
    const double w = p * m->par[P_OMEGA - P_R], te = p * th_m, c = cos(te), s = sin(te);
    const double vd = c * m->io[V_ALPHA] + s * m->io[V_BETA], vq = -s * m->io[V_ALPHA] + c * m->io[V_BETA];
    *did = (vd - R * id + w * Lq * iq) / Ld;
    *diq = (vq - R * iq - w * Ld * id - w * psi) / Lq;
}

static void advance(model_t *m, double h_total)
{
    const int n = (int)(m->par[P_SUBSTEPS - P_R] >= 1.0 ? m->par[P_SUBSTEPS - P_R] : 1.0);
    const double h = h_total / n, wm = m->par[P_OMEGA - P_R];
    for (int k = 0; k < n; ++k) {
        const double th = m->theta_m;
        double a1, b1, a2, b2, a3, b3, a4, b4;
        deriv(m, th, m->id, m->iq, &a1, &b1);
        deriv(m, th + 0.5 * h * wm, m->id + 0.5 * h * a1, m->iq + 0.5 * h * b1, &a2, &b2);
        deriv(m, th + 0.5 * h * wm, m->id + 0.5 * h * a2, m->iq + 0.5 * h * b2, &a3, &b3);
        deriv(m, th + h * wm, m->id + h * a3, m->iq + h * b3, &a4, &b4);
        m->id += h / 6.0 * (a1 + 2.0 * (a2 + a3) + a4);
        m->iq += h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4);
        m->theta_m += h * wm;
    }
}

/* ------------------------------------------------------------------ FMI 2.0 */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    (void)c, (void)on, (void)n, (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging)
{
    (void)name, (void)resources, (void)functions, (void)visible, (void)logging;
    if (type != fmi2CoSimulation || guid == NULL || strcmp(guid, "{3f7c2a1e-5b8d-4e2a-9c41-7d6b0e8a1f42}") != 0)
        return NULL;
    model_t *m = calloc(1, sizeof *m);
    if (m == NULL) return NULL;
    memcpy(m->par, k_defaults, sizeof m->par);
    reset_state(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start, fmi2Boolean stopDef,
                               fmi2Real stop)
{
    (void)c, (void)tolDef, (void)tol, (void)start, (void)stopDef, (void)stop;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    reset_state((model_t *)c);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    model_t *m = (model_t *)c;
    memcpy(m->par, k_defaults, sizeof m->par);
    memset(m->io, 0, sizeof m->io);
    reset_state(m);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    for (size_t i = 0; i < n; ++i) {
        double *p = ref((model_t *)c, vr[i]);
        if (p == NULL) return fmi2Error;
        v[i] = *p;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[])
{
    for (size_t i = 0; i < n; ++i) {
        double *p = ref((model_t *)c, vr[i]);
        if (p == NULL || vr[i] == I_A || vr[i] == I_B || vr[i] == THETA_M || vr[i] == OMEGA_M) return fmi2Error;
        *p = v[i];
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    (void)noSetPrior;
    model_t *m = (model_t *)c;
    const double fail_at = m->par[P_FAIL_AT - P_R];
    if (m->failed || (fail_at > 0.0 && t >= fail_at)) {
        m->failed = 1;
        return fmi2Error;
    }
    advance(m, h);
    outputs(m);
    return fmi2OK;
}

/* ------------------------------------------------------------------ the rest of the interface: not used */

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{
    (void)c, (void)vr, (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)c, (void)s;
    return fmi2Error;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    (void)c, (void)s;
    return fmi2Error;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)c, (void)s;
    return fmi2Error;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{
    (void)c, (void)s, (void)n;
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{
    (void)c, (void)s, (void)b, (void)n;
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{
    (void)c, (void)b, (void)n, (void)s;
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference k[], size_t nk, const fmi2Real dk[], fmi2Real du[])
{
    (void)c, (void)u, (void)nu, (void)k, (void)nk, (void)dk, (void)du;
    return fmi2Error;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)v;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)v;
    return fmi2Error;
}
fmi2Status fmi2CancelStep(fmi2Component c)
{
    (void)c;
    return fmi2Error;
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{
    (void)c, (void)s, (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{
    (void)c, (void)s, (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{
    (void)c, (void)s, (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{
    (void)c, (void)s, (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{
    (void)c, (void)s, (void)v;
    return fmi2Discard;
}

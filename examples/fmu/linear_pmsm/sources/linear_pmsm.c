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
#include "fmi2Functions.h"

#include "linear_pmsm_model.h"

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
    model_init(m);
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
    model_init((model_t *)c);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    return model_get((model_t *)c, vr, n, v) == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[])
{
    return model_set((model_t *)c, vr, n, v) == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    (void)noSetPrior;
    return model_do_step((model_t *)c, t, h) == 0 ? fmi2OK : fmi2Error;
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

/* linear_pmsm_fmi3.c - the example linear PMSM (linear_pmsm_model.h, the model of examples/fmu/linear_pmsm) as an
 * FMI 3.0 co-simulation FMU.  It exports what a co-simulation master calls: instantiate (co-simulation only),
 * initialization, Float64 get and set, doStep, terminate, reset, free; the other 3.0 functions are not exported
 * (a master that needs them, model exchange or scheduled execution, refuses this FMU when it loads it). */
#include "fmi3Functions.h"

#include "linear_pmsm_model.h"

#define TOKEN "{6d0a5c3e-2f41-4b7e-8e9a-1c3b5d7f9a20}"

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[])
{
    (void)c, (void)on, (void)n, (void)cats;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                         fmi3Boolean logging, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturn,
                                         const fmi3ValueReference required[], size_t nRequired,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback update)
{
    (void)name, (void)resources, (void)visible, (void)logging, (void)earlyReturn, (void)required, (void)nRequired;
    (void)env, (void)log, (void)update;
    if (eventModeUsed || token == NULL || strcmp(token, TOKEN) != 0) return NULL;
    model_t *m = calloc(1, sizeof *m);
    if (m == NULL) return NULL;
    model_init(m);
    return m;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolDef, fmi3Float64 tol, fmi3Float64 start,
                                       fmi3Boolean stopDef, fmi3Float64 stop)
{
    (void)c, (void)tolDef, (void)tol, (void)start, (void)stopDef, (void)stop;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c)
{
    reset_state((model_t *)c);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c)
{
    (void)c;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c)
{
    model_init((model_t *)c);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv)
{
    return nv == n && model_get((model_t *)c, vr, n, v) == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv)
{
    return nv == n && model_set((model_t *)c, vr, n, v) == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior, fmi3Boolean *eventNeeded,
                      fmi3Boolean *terminate, fmi3Boolean *earlyReturn, fmi3Float64 *lastTime)
{
    (void)noSetPrior;
    *eventNeeded = fmi3False;
    *terminate = fmi3False;
    *earlyReturn = fmi3False;
    if (model_do_step((model_t *)c, t, h) != 0) return fmi3Error;
    *lastTime = t + h;
    return fmi3OK;
}

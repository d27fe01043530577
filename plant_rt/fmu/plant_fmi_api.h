/* plant_fmi_api.h - the part of the FMI 2.0 and FMI 3.0 co-simulation C interface the plant's FMU loader uses
 * (plant_fmu.c), written for this project from the FMI specification, so that the plant builds without any
 * external FMI header (a pip install compiles it where FMPy cannot be imported).
 *
 * Only the binary interface is declared: the types the loader passes, the status values it compares, FMI 2's
 * callback record and a pointer type for each function the loader finds in the FMU's library with dlsym (under the
 * standard's plain names, fmi2DoStep, fmi3DoStep, ...: the FMU's exported symbols).  The names here are ours
 * (plant_fmi2_, plant_fmi3_), the layouts, values and calling signatures are the standard's:
 *
 *   FMI 2.0.x ("Functional Mock-up Interface for Model Exchange and Co-Simulation", 2.0 and its maintenance
 *   releases), section 2.1.2 Platform Dependent Definitions (the standard's platform: fmi2Real double,
 *   fmi2Boolean int, fmi2ValueReference unsigned int, fmi2String a const char pointer, fmi2Component a void
 *   pointer), 2.1.3 Status Returned by Functions, 2.1.5 Creation, Destruction and Logging of
 *   FMU Instances (fmi2Instantiate, fmi2FreeInstance, the callback functions), 2.1.6 Initialization,
 *   Termination, and Resetting an FMU, 2.1.7 Getting and Setting Variable Values, 4.2.2 Computation
 *   (fmi2DoStep).
 *
 *   FMI 3.0 ("Functional Mock-up Interface Specification", 3.0 / 3.0.x), section 2.2 (Header Files and Naming
 *   of Functions, Platform Dependent Definitions: fmi3Float64 double, fmi3Boolean bool, fmi3ValueReference
 *   uint32_t; Status Returned by Functions), and the functions of its API: fmi3InstantiateCoSimulation with its
 *   logMessage and intermediateUpdate callbacks, fmi3FreeInstance, fmi3EnterInitializationMode,
 *   fmi3ExitInitializationMode, fmi3Terminate, fmi3Reset, fmi3GetFloat64 / fmi3SetFloat64 and fmi3DoStep.
 *
 * The FMU is a Linux x86-64 binary (binaries/linux64 in 2.0, x86_64-linux in 3.0): int and unsigned int are 32
 * bits there, so FMI 2's int and unsigned int are written int32_t and uint32_t (the same C types on that
 * platform).  The standard declares its statuses and FMI 2's fmuType as C enums, whose integer type C leaves to
 * the compiler (GCC and Clang: unsigned int for these non-negative values, 4 bytes as the x86-64 psABI asks);
 * here they are uint32_t with the standard's values as constants: the same size, passing and return register. */
#ifndef PLANT_FMI_API_H
#define PLANT_FMI_API_H

#include <limits.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

_Static_assert(sizeof(int) == sizeof(int32_t) && INT_MAX == INT32_MAX, "FMI 2's int: 32 bits on linux64");
_Static_assert(sizeof(unsigned int) == sizeof(uint32_t) && UINT_MAX == UINT32_MAX,
               "FMI 2's unsigned int: 32 bits on linux64");

/* ------------------------------------------------------------------ FMI 2.0 (co-simulation) */

typedef void *plant_fmi2_component_t;   /* an instance (fmi2Component) */
typedef void *plant_fmi2_environment_t; /* the importer's pointer handed back to its callbacks */
typedef const char *plant_fmi2_string_t;
typedef uint32_t plant_fmi2_value_ref_t; /* a variable's valueReference */
typedef int32_t plant_fmi2_boolean_t;

#define PLANT_FMI2_FALSE 0
#define PLANT_FMI2_TRUE 1

/* A function's result (fmi2Status): OK, warning (go on), discard, error, fatal, pending (asynchronous step). */
typedef uint32_t plant_fmi2_status_t;
enum {
    PLANT_FMI2_OK = 0,
    PLANT_FMI2_WARNING = 1,
    PLANT_FMI2_DISCARD = 2,
    PLANT_FMI2_ERROR = 3,
    PLANT_FMI2_FATAL = 4,
    PLANT_FMI2_PENDING = 5,
};

/* The kind of instance asked of fmi2Instantiate (fmi2Type). */
typedef uint32_t plant_fmi2_kind_t;
enum { PLANT_FMI2_MODEL_EXCHANGE = 0, PLANT_FMI2_CO_SIMULATION = 1 };

/* The importer's services the FMU calls: a printf-like log line (format and arguments after the message),
 * calloc- and free-like memory, and the end of an asynchronous step. */
typedef void (*plant_fmi2_logger_fn)(plant_fmi2_environment_t env, plant_fmi2_string_t instance_name,
                                     plant_fmi2_status_t status, plant_fmi2_string_t category,
                                     plant_fmi2_string_t message, ...);
typedef void *(*plant_fmi2_alloc_fn)(size_t count, size_t size);
typedef void (*plant_fmi2_free_fn)(void *block);
typedef void (*plant_fmi2_step_finished_fn)(plant_fmi2_environment_t env, plant_fmi2_status_t status);

/* fmi2CallbackFunctions: five pointers in this order (the FMU keeps the record's address). */
typedef struct {
    plant_fmi2_logger_fn logger;
    plant_fmi2_alloc_fn allocate;
    plant_fmi2_free_fn release;
    plant_fmi2_step_finished_fn step_finished; /* may be NULL */
    plant_fmi2_environment_t env;
} plant_fmi2_callbacks_t;

/* fmi2Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation (a URI), functions, visible, loggingOn):
 * the instance, or NULL. */
typedef plant_fmi2_component_t (*plant_fmi2_instantiate_fn)(plant_fmi2_string_t instance_name, plant_fmi2_kind_t kind,
                                                            plant_fmi2_string_t guid, plant_fmi2_string_t resource_uri,
                                                            const plant_fmi2_callbacks_t *callbacks,
                                                            plant_fmi2_boolean_t visible,
                                                            plant_fmi2_boolean_t logging_on);
typedef void (*plant_fmi2_free_instance_fn)(plant_fmi2_component_t c);
/* fmi2SetupExperiment(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime) */
typedef plant_fmi2_status_t (*plant_fmi2_setup_experiment_fn)(plant_fmi2_component_t c,
                                                              plant_fmi2_boolean_t tolerance_defined, double tolerance,
                                                              double start_time, plant_fmi2_boolean_t stop_defined,
                                                              double stop_time);
/* fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2Terminate, fmi2Reset: the instance alone. */
typedef plant_fmi2_status_t (*plant_fmi2_instance_fn)(plant_fmi2_component_t c);
/* fmi2SetReal(c, vr[], nvr, value[]) */
typedef plant_fmi2_status_t (*plant_fmi2_set_real_fn)(plant_fmi2_component_t c, const plant_fmi2_value_ref_t vr[],
                                                      size_t n, const double value[]);
/* fmi2GetReal(c, vr[], nvr, value[]) */
typedef plant_fmi2_status_t (*plant_fmi2_get_real_fn)(plant_fmi2_component_t c, const plant_fmi2_value_ref_t vr[],
                                                      size_t n, double value[]);
/* fmi2DoStep(c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint) */
typedef plant_fmi2_status_t (*plant_fmi2_do_step_fn)(plant_fmi2_component_t c, double t, double h,
                                                     plant_fmi2_boolean_t no_state_before_t);

/* ------------------------------------------------------------------ FMI 3.0 (co-simulation) */

typedef void *plant_fmi3_instance_t;    /* an instance (fmi3Instance) */
typedef void *plant_fmi3_environment_t; /* the importer's pointer handed back to its callbacks */
typedef const char *plant_fmi3_string_t;
typedef uint32_t plant_fmi3_value_ref_t;

/* A function's result (fmi3Status): OK, warning (go on), discard, error, fatal. */
typedef uint32_t plant_fmi3_status_t;
enum {
    PLANT_FMI3_OK = 0,
    PLANT_FMI3_WARNING = 1,
    PLANT_FMI3_DISCARD = 2,
    PLANT_FMI3_ERROR = 3,
    PLANT_FMI3_FATAL = 4,
};

/* logMessage(instanceEnvironment, status, category, message): a finished text, no format. */
typedef void (*plant_fmi3_log_fn)(plant_fmi3_environment_t env, plant_fmi3_status_t status,
                                  plant_fmi3_string_t category, plant_fmi3_string_t message);
/* intermediateUpdate(instanceEnvironment, intermediateUpdateTime, intermediateVariableSetRequested,
 * intermediateVariableGetAllowed, intermediateStepFinished, canReturnEarly, earlyReturnRequested (out),
 * earlyReturnTime (out)); the loader passes none (NULL). */
typedef void (*plant_fmi3_intermediate_fn)(plant_fmi3_environment_t env, double t, bool set_requested, bool get_allowed,
                                           bool step_finished, bool can_return_early, bool *early_return_requested,
                                           double *early_return_time);

/* fmi3InstantiateCoSimulation(instanceName, instantiationToken, resourcePath (a directory, or NULL), visible,
 * loggingOn, eventModeUsed, earlyReturnAllowed, requiredIntermediateVariables[], nRequiredIntermediateVariables,
 * instanceEnvironment, logMessage, intermediateUpdate): the instance, or NULL. */
typedef plant_fmi3_instance_t (*plant_fmi3_instantiate_cs_fn)(
    plant_fmi3_string_t instance_name, plant_fmi3_string_t token, plant_fmi3_string_t resource_path, bool visible,
    bool logging_on, bool event_mode_used, bool early_return_allowed, const plant_fmi3_value_ref_t required[],
    size_t n_required, plant_fmi3_environment_t env, plant_fmi3_log_fn log, plant_fmi3_intermediate_fn update);
typedef void (*plant_fmi3_free_instance_fn)(plant_fmi3_instance_t inst);
/* fmi3EnterInitializationMode(instance, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime) */
typedef plant_fmi3_status_t (*plant_fmi3_enter_init_fn)(plant_fmi3_instance_t inst, bool tolerance_defined,
                                                        double tolerance, double start_time, bool stop_defined,
                                                        double stop_time);
/* fmi3ExitInitializationMode, fmi3Terminate, fmi3Reset: the instance alone. */
typedef plant_fmi3_status_t (*plant_fmi3_instance_fn)(plant_fmi3_instance_t inst);
/* fmi3SetFloat64(instance, valueReferences[], nValueReferences, values[], nValues): nValues counts the array
 * elements (the scalars' number for scalars). */
typedef plant_fmi3_status_t (*plant_fmi3_set_float64_fn)(plant_fmi3_instance_t inst, const plant_fmi3_value_ref_t vr[],
                                                         size_t n_vr, const double values[], size_t n_values);
/* fmi3GetFloat64(instance, valueReferences[], nValueReferences, values[], nValues) */
typedef plant_fmi3_status_t (*plant_fmi3_get_float64_fn)(plant_fmi3_instance_t inst, const plant_fmi3_value_ref_t vr[],
                                                         size_t n_vr, double values[], size_t n_values);
/* fmi3DoStep(instance, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint,
 * eventHandlingNeeded (out), terminateSimulation (out), earlyReturn (out), lastSuccessfulTime (out)) */
typedef plant_fmi3_status_t (*plant_fmi3_do_step_fn)(plant_fmi3_instance_t inst, double t, double h,
                                                     bool no_state_before_t, bool *event_handling_needed,
                                                     bool *terminate, bool *early_return, double *last_time);

#endif

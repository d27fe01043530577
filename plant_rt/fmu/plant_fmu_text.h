/* plant_fmu_text.h - the spec of a co-simulation FMU as the plant's object 0x2009 "FMU" gives it (the text's lines:
 * plant_fmu.h), and its parser (plant_fmu_text.c). */
#ifndef PLANT_FMU_TEXT_H
#define PLANT_FMU_TEXT_H

#include <stddef.h>
#include <stdint.h>

#define PLANT_FMU_MAX_PARAMS 32

typedef enum { PLANT_FMU_AB = 0, PLANT_FMU_DQ = 1, PLANT_FMU_PHASE = 2 } plant_fmu_frame_t;

typedef struct {
    int fmi;
    char library[1024];
    char identifier[256];
    char token[256];
    char resources[1100];
    plant_fmu_frame_t inputs, outputs;
    uint32_t in_vr[2], out_vr[2], theta_vr, omega_vr;
    int has_omega;
    int pole_pairs;
    uint32_t substeps;
    uint32_t param_vr[PLANT_FMU_MAX_PARAMS];
    double param_value[PLANT_FMU_MAX_PARAMS];
    uint32_t n_params;
} plant_fmu_spec_t;

/* The spec of a 0x2009 text; 0, or -1 with the reason in err. */
int plant_fmu_parse(const char *text, size_t len, plant_fmu_spec_t *spec, char *err, size_t err_len);

/* printf into err (n bytes; err NULL: nothing): a refusal's message. */
void plant_fmu_say(char *err, size_t n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif

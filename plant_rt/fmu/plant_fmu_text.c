/* plant_fmu_text.c - the text of the plant's object 0x2009 "FMU" (plant_fmu_text.h; its lines: plant_fmu.h) parsed
 * into a spec, each refusal named.  Host glue (stdio for the messages). */
#include "plant_fmu_text.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void plant_fmu_say(char *err, size_t n, const char *fmt, ...)
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
        plant_fmu_say(err, n, "0x2009 FMU: unknown key %s", key);
        return -1;
    }
    if (bad) plant_fmu_say(err, n, "0x2009 FMU: bad value for %s: %s", key, val);
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
            plant_fmu_say(err, err_len, "0x2009 FMU: a line longer than %zu characters", sizeof line - 1);
            return -1;
        }
        memcpy(line, text + i, n);
        line[n] = '\0';
        i = j + 1;
        if (n == 0) continue;
        char *sp = strchr(line, ' ');
        if (sp == NULL) {
            plant_fmu_say(err, err_len, "0x2009 FMU: line without a value: %s", line);
            return -1;
        }
        *sp = '\0';
        if (take(spec, line, sp + 1, err, err_len) != 0) return -1;
        const char *keys[] = {"fmi", "library", "token", "in0", "in1", "out0", "out1", "theta"};
        for (unsigned k = 0; k < 8u; ++k)
            if (strcmp(line, keys[k]) == 0) seen |= 1u << k;
    }
    if (seen != 0xFFu) {
        plant_fmu_say(err, err_len, "0x2009 FMU: fmi, library, token, in0, in1, out0, out1 and theta are required");
        return -1;
    }
    return 0;
}

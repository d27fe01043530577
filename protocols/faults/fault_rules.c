/* fault_rules.c - see fault_rules.h. */
#include "fault_rules.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const KIND_NAMES[] = {"pass",   "drop", "delay", "duplicate", "corrupt", "reorder",
                                         "freeze", "thaw", "kill",  "reset",     "release"};

const char *fi_kind_name(uint8_t kind)
{
    return kind < sizeof KIND_NAMES / sizeof KIND_NAMES[0] ? KIND_NAMES[kind] : "?";
}

static int parse_u64(const char *v, unsigned long long max, unsigned long long *out)
{
    char *end = NULL;
    if (*v == '-' || *v == '\0') return -1;
    unsigned long long x = strtoull(v, &end, 0);
    if (*end != '\0' || x > max) return -1;
    *out = x;
    return 0;
}

static int set_field(fi_rule_t *r, const char *key, const char *v)
{
    unsigned long long u = 0;
    if (strcmp(key, "kind") == 0) {
        for (uint8_t k = FI_DROP; k <= FI_RESET; ++k)
            if (k != FI_THAW && strcmp(v, KIND_NAMES[k]) == 0) {
                r->kind = k;
                return 0;
            }
        return -1;
    }
    if (strcmp(key, "from") == 0) {
        if (strcmp(v, "a") == 0)
            r->from = FI_SIDE_A;
        else if (strcmp(v, "b") == 0)
            r->from = FI_SIDE_B;
        else if (strcmp(v, "any") == 0)
            r->from = FI_SIDE_ANY;
        else
            return -1;
        return 0;
    }
    if (strcmp(key, "cob") == 0) {
        if (strcmp(v, "any") == 0) {
            r->cob_id = FI_ANY_COB;
            return 0;
        }
        if (parse_u64(v, 0x7FF, &u)) return -1;
        r->cob_id = (uint16_t)u;
        return 0;
    }
    if (strcmp(key, "prob") == 0) {
        char *end = NULL;
        double p = strtod(v, &end);
        if (*end != '\0' || !(p > 0.0 && p <= 1.0)) return -1;
        r->threshold = p >= 1.0 ? FI_ALWAYS : (uint64_t)(p * 4294967296.0);
        return 0;
    }
    if (strcmp(key, "dlc") == 0) {
        if (strcmp(v, "-1") == 0) {
            r->dlc = -1;
            return 0;
        }
        if (parse_u64(v, 8, &u)) return -1;
        r->dlc = (int8_t)u;
        return 0;
    }
    struct {
        const char *name;
        unsigned long long max;
    } const ints[] = {
        {"at", 0xFFFFFFFFull},         {"periods", 0xFFFFFFFFull}, {"seed", ~0ull}, {"count", 0xFFFFFFFFull},
        {"delay_periods", 1000000ull}, {"delay_us", 10000000ull},  {"bit", 63ull},  {"node_id", 127ull}};
    for (size_t i = 0; i < sizeof ints / sizeof ints[0]; ++i) {
        if (strcmp(key, ints[i].name) != 0) continue;
        if (parse_u64(v, ints[i].max, &u)) return -1;
        switch (i) {
        case 0: r->at_period = (uint32_t)u; break;
        case 1: r->periods = (uint32_t)u; break;
        case 2: r->seed = u; break;
        case 3: r->count = (uint32_t)u; break;
        case 4: r->delay_periods = (uint32_t)u; break;
        case 5: r->delay_us = (uint32_t)u; break;
        case 6: r->bit = (uint8_t)u; break;
        default: r->node_id = (uint8_t)u; break;
        }
        return 0;
    }
    return -2;
}

int fi_parse_rules(fi_t *fi, const char *text, char *err, size_t err_len)
{
    int added = 0, line_no = 0;
    const char *p = text;
    while (*p) {
        char line[512];
        const char *nl = strchr(p, '\n');
        size_t n = nl ? (size_t)(nl - p) : strlen(p);
        ++line_no;
        if (n >= sizeof line) {
            snprintf(err, err_len, "fault rule line %d: longer than %zu characters", line_no, sizeof line - 1);
            return -1;
        }
        memcpy(line, p, n);
        line[n] = '\0';
        p += n + (nl ? 1 : 0);
        char *hash = strchr(line, '#');
        if (hash) *hash = '\0';
        fi_rule_t r;
        memset(&r, 0, sizeof r);
        r.from = FI_SIDE_ANY;
        r.cob_id = FI_ANY_COB;
        r.periods = 1u;
        r.threshold = FI_ALWAYS;
        r.dlc = -1;
        int fields = 0;
        long period_cob = -1;
        for (char *tok = strtok(line, " \t\r"); tok; tok = strtok(NULL, " \t\r")) {
            char *eq = strchr(tok, '=');
            if (!eq) {
                snprintf(err, err_len, "fault rule line %d: %s: expected key=value", line_no, tok);
                return -1;
            }
            *eq = '\0';
            unsigned long long cob = 0;
            if (strcmp(tok, "period_cob") == 0 && parse_u64(eq + 1, 0x7FF, &cob) == 0) {
                period_cob = (long)cob;
                continue;
            }
            int rc = set_field(&r, tok, eq + 1);
            if (rc == -2) {
                snprintf(err, err_len, "fault rule line %d: unknown key %s", line_no, tok);
                return -1;
            }
            if (rc != 0) {
                snprintf(err, err_len, "fault rule line %d: %s=%s: bad value", line_no, tok, eq + 1);
                return -1;
            }
            ++fields;
        }
        if (period_cob >= 0 && fields == 0) { /* `period_cob=0x190`: the frame that starts a period (fi_t.sync_cob) */
            fi->sync_cob = (uint16_t)period_cob;
            continue;
        }
        if (period_cob >= 0) {
            snprintf(err, err_len, "fault rule line %d: period_cob= stands on a line of its own", line_no);
            return -1;
        }
        if (fields == 0) continue;
        if (r.kind == 0) {
            snprintf(err, err_len, "fault rule line %d: kind= is missing", line_no);
            return -1;
        }
        if (fi_add_rule(fi, &r) < 0) {
            snprintf(err, err_len, "fault rule line %d: refused (more than %u rules, or kind %s with from=%s)", line_no,
                     FI_MAX_RULES, fi_kind_name(r.kind),
                     r.from == FI_SIDE_A   ? "a"
                     : r.from == FI_SIDE_B ? "b"
                                           : "any");
            return -1;
        }
        ++added;
    }
    return added;
}

/* law_states.h - the tests' look inside the selected law's state (drive_t.law_state). */
#ifndef LAW_STATES_H
#define LAW_STATES_H

#include "yao2020_identification.h"
#include "yao2020_law.h"
#include "you2019_law.h"
#include "zhao2022_law.h"

#define YOU2019_OF(d) ((you2019_law_state_t *)(void *)(d).law_state)
#define YAO2020_OF(d) ((yao2020_law_state_t *)(void *)(d).law_state)

#endif

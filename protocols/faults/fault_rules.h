/* fault_rules.h - the injector's rules as text, one rule a line, the one format the bench writes
 * for both transports (direct mode through ctypes, the gateway process from a file):
 *
 *   kind=drop from=b cob=0x1A0 at=200 periods=1 prob=1 seed=7 count=0
 *   kind=delay from=b cob=0x1A0 at=200 delay_periods=1      kind=delay ... delay_us=300
 *   kind=corrupt from=a cob=0x190 at=50 bit=31              kind=corrupt ... dlc=4
 *   kind=freeze from=b at=100 periods=5    kind=kill from=b at=100    kind=reset from=b at=100 node_id=0x20
 *
 *   period_cob=0x190      (a line of its own: the identifier whose frames from side a start the periods;
 *                          default the SYNC's, 0x080; the plant's measurement frame when it marks the period)
 *
 * kinds: drop delay duplicate corrupt reorder freeze kill reset; from: a (plant side) | b (drive
 * side) | any; cob: 0..0x7FF or any. Unknown keys and bad values are refused (the bench validates
 * the scenario first; this is the last line of defence). Uses the C library only (strtoul, strtod).
 */
#ifndef FAULT_RULES_H
#define FAULT_RULES_H

#include <stddef.h>

#include "fault_injector.h"

/* Add every rule of `text` (lines; '#' starts a comment). Returns the number added, or -1 with
 * a message in err (line number and the bad field). */
int fi_parse_rules(fi_t *fi, const char *text, char *err, size_t err_len);

/* Name of a fi_kind_t ("drop", ..., "release"). */
const char *fi_kind_name(uint8_t kind);

#endif /* FAULT_RULES_H */

/* co_od.h - object dictionary access for the portable CANopen slave.
 *
 * The tables are generated from the EDS files by protocols/gen_od.py
 * (protocols/generated/od_<node>.c); this header is the contract they follow.
 * Every access that can fail returns a CiA 301 SDO abort code (0 = success).
 */
#ifndef CO_OD_H
#define CO_OD_H

#include <stddef.h>
#include <stdint.h>

/* CiA 301 data types used by the bench. */
enum {
    CO_DT_BOOLEAN = 0x01,
    CO_DT_INTEGER8 = 0x02,
    CO_DT_INTEGER16 = 0x03,
    CO_DT_INTEGER32 = 0x04,
    CO_DT_UNSIGNED8 = 0x05,
    CO_DT_UNSIGNED16 = 0x06,
    CO_DT_UNSIGNED32 = 0x07,
    CO_DT_REAL32 = 0x08,
    CO_DT_VISIBLE_STRING = 0x09,
    CO_DT_DOMAIN = 0x0F
};

/* Entry flags. */
#define CO_ODF_READ 0x01u   /* readable by SDO */
#define CO_ODF_WRITE 0x02u  /* writable by SDO */
#define CO_ODF_PDO 0x04u    /* PDO-mappable */
#define CO_ODF_NODEID 0x08u /* default value is relative to the node-ID ($NODEID+...) */
#define CO_ODF_LIMITS 0x10u /* LowLimit/HighLimit from the EDS apply to writes */

/* SDO abort codes (CiA 301 table 22). */
#define CO_ABORT_TOGGLE 0x05030000u
#define CO_ABORT_TIMEOUT 0x05040000u
#define CO_ABORT_CMD 0x05040001u
#define CO_ABORT_BLOCK_SIZE 0x05040002u
#define CO_ABORT_OUT_OF_MEMORY 0x05040005u
#define CO_ABORT_UNSUPPORTED 0x06010000u
#define CO_ABORT_WRITE_ONLY 0x06010001u
#define CO_ABORT_READ_ONLY 0x06010002u
#define CO_ABORT_NO_OBJECT 0x06020000u
#define CO_ABORT_NO_MAP 0x06040041u
#define CO_ABORT_MAP_LEN 0x06040042u
#define CO_ABORT_PARAM_INCOMPAT 0x06040043u
#define CO_ABORT_HW 0x06060000u
#define CO_ABORT_TYPE_MISMATCH 0x06070010u
#define CO_ABORT_TOO_LONG 0x06070012u
#define CO_ABORT_TOO_SHORT 0x06070013u
#define CO_ABORT_NO_SUB 0x06090011u
#define CO_ABORT_INVALID_VALUE 0x06090030u
#define CO_ABORT_VALUE_HIGH 0x06090031u
#define CO_ABORT_VALUE_LOW 0x06090032u
#define CO_ABORT_GENERAL 0x08000000u
#define CO_ABORT_DATA_TRANSFER 0x08000020u
#define CO_ABORT_DATA_LOCAL 0x08000021u
#define CO_ABORT_DATA_STATE 0x08000022u

/* A DOMAIN object: the application points `data` at its buffer. */
typedef struct {
    uint8_t *data;
    uint32_t size;     /* valid bytes (uploads read this many) */
    uint32_t capacity; /* bytes a download may write (0: read-only buffer) */
} co_domain_t;

typedef union {
    int64_t i;
    float f;
} co_limit_t;

typedef struct {
    uint16_t index;
    uint8_t subindex;
    uint8_t datatype;
    uint8_t flags;
    uint32_t size; /* bytes; capacity without the NUL for VISIBLE_STRING; 0 for DOMAIN */
    void *data;    /* storage in the generated RAM struct */
    co_limit_t low, high;
} co_od_entry_t;

typedef struct {
    const co_od_entry_t *entries; /* sorted by (index, subindex) */
    uint16_t count;
    void *ram;            /* the generated RAM struct (communication part first) */
    const void *defaults; /* its EDS default values */
    size_t comm_size;     /* bytes of the communication part (0x1000-0x1FFF) */
    size_t total_size;
} co_od_t;

/* An object bound to its owner (CANopenNode's OD_extension_t): the owner keeps this struct in its own state and
 * binds it to one object (index) once at init (co_node_bind). The node's SDO and PDO paths then call the object's
 * own handlers, each optional:
 *   read     about to be uploaded by SDO or sent in a TPDO: refresh the object's values (a TPDO calls it once
 *            for consecutive mapped entries of the object);
 *   check    an SDO write, after the node's generic checks (length, range, access, the communication rules):
 *            an abort code, or 0 to accept;
 *   written  an SDO write was stored (the OD holds the new value): put it into effect.
 * PDO writes (RPDOs) bypass check and written: the owner reads its PDO-mapped values when it uses them. */
typedef struct co_od_ext {
    void *object; /* the owner's state, handed back to each handler */
    void (*read)(void *object, const co_od_entry_t *e);
    uint32_t (*check)(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
    void (*written)(void *object, const co_od_entry_t *e);
} co_od_ext_t;

/* Entry lookup (binary search). Returns NULL if absent; *index_exists tells
 * whether any sub-index of `index` exists (for 0x06020000 vs 0x06090011). */
const co_od_entry_t *co_od_find(const co_od_t *od, uint16_t index, uint8_t subindex, int *index_exists);

/* Current byte length of an entry's value (strings: without NUL; domains: size). */
uint32_t co_od_value_size(const co_od_entry_t *e);

/* Raw little-endian copy of a value into buf (at most cap bytes). Returns the length. */
uint32_t co_od_read_raw(const co_od_entry_t *e, uint32_t offset, uint8_t *buf, uint32_t cap);

/* Checks length and range of a write of `len` bytes; does not check access. */
uint32_t co_od_check_write(const co_od_entry_t *e, const uint8_t *buf, uint32_t len);

/* Stores a checked value (little-endian bytes). */
void co_od_store(const co_od_entry_t *e, const uint8_t *buf, uint32_t len);

/* Convenience accessors for the node's own code (no access or range checks). */
uint32_t co_od_get_u32(const co_od_t *od, uint16_t index, uint8_t sub);
void co_od_set_u32(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t value);

/* Restore EDS defaults: the communication area only, or everything; node-ID
 * relative defaults get `node_id` added. */
void co_od_reset(const co_od_t *od, uint8_t node_id, int communication_only);

/* CiA 301 restricted CAN-IDs (NMT, SDO, NMT error control, LSS ...): never usable as a
 * SYNC, EMCY or PDO identifier. */
int co_cob_restricted(uint32_t cob_id);

/* 1 on a little-endian host (CANopen's byte order: values are copied as they are), 0 on a big-endian one. */
int co_host_is_little(void);

/* Size in bytes of a fixed-size data type (0 for strings and domains). */
uint32_t co_dt_size(uint8_t datatype);

#endif /* CO_OD_H */

/* co_fd.c - a node's CAN FD PDOs (see co_fd.h). */
#include "co_fd.h"

#include "co_frame.h"

void co_fd_attach(co_fd_t *fd, const co_od_t *od)
{
    const co_od_entry_t *ff = co_od_find(od, CO_IDX_CAN_FD, 1, NULL);
    const co_od_entry_t *ct = co_od_find(od, CO_IDX_CAN_FD, 2, NULL);
    fd->frame_format = ff != NULL ? (const uint8_t *)ff->data : NULL;
    fd->classic_tpdos = ct != NULL ? (const uint8_t *)ct->data : NULL;
}

uint32_t co_fd_check_write(const co_od_entry_t *e, const uint8_t *data, bool operational)
{
    if (e->index != CO_IDX_CAN_FD) return 0;
    if (operational) return CO_ABORT_DATA_STATE;
    if (e->subindex == 1u && data[0] != 0u && CO_FRAME_MAX_DATA <= 8u) return CO_ABORT_VALUE_HIGH;
    return 0;
}

uint8_t co_fd_flags(const co_fd_t *fd, bool is_tpdo, uint8_t n)
{
    if (fd->frame_format == NULL || *fd->frame_format == 0u) return 0u;
    if (is_tpdo && fd->classic_tpdos != NULL && ((*fd->classic_tpdos >> n) & 1u)) return 0u;
    return *fd->frame_format >= 2u ? (uint8_t)(CO_FRAME_FDF | CO_FRAME_BRS) : (uint8_t)CO_FRAME_FDF;
}

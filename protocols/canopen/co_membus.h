/* co_membus.h - an in-process CAN bus for the portable CANopen nodes.
 *
 * It behaves like a CAN bus with one ordered queue: every frame a node sends is
 * delivered, in order, to every other attached node and to the recorder (a
 * CAN controller does not receive its own frames). The bench's direct mode runs
 * the plant and the drive on it in-process: same code, same frames, no kernel.
 * No allocation: the queue and the node table are fixed-size.
 */
#ifndef CO_MEMBUS_H
#define CO_MEMBUS_H

#include <stdint.h>

#include "co_frame.h"
#include "co_node.h"

#define CO_MEMBUS_QUEUE 512u
#define CO_MEMBUS_NODES 4u
#define CO_MEMBUS_EXTERNAL 0xFFu /* sender index of frames injected from outside (e.g. the bench master) */

typedef struct co_membus co_membus_t;

/* Transmit context of one attached node: pass &port as tx_user with co_membus_tx. */
typedef struct {
    co_membus_t *bus;
    uint8_t index;
} co_membus_port_t;

/* Called for every frame on the bus (the recorder / the external master's receiver). */
typedef void (*co_membus_sink_fn)(void *user, const co_frame_t *frame, uint8_t sender, int64_t now_us);

struct co_membus {
    co_frame_t queue[CO_MEMBUS_QUEUE];
    uint8_t sender[CO_MEMBUS_QUEUE];
    uint32_t head, tail;
    co_node_t *nodes[CO_MEMBUS_NODES];
    co_membus_port_t ports[CO_MEMBUS_NODES];
    uint8_t n_nodes;
    co_membus_sink_fn sink;
    void *sink_user;
    uint32_t overflows;
    uint64_t frames;
};

void co_membus_init(co_membus_t *bus, co_membus_sink_fn sink, void *sink_user);
/* Reserve a port; returns its index or -1. Attach the node after co_node_init. */
int co_membus_port(co_membus_t *bus);
void co_membus_attach(co_membus_t *bus, int port, co_node_t *node);
/* co_tx_fn: queue a frame from the node whose port is `user`. */
int co_membus_tx(void *user, const co_frame_t *frame);
/* Queue a frame from outside (the bench master). */
int co_membus_inject(co_membus_t *bus, const co_frame_t *frame);
/* Deliver queued frames (and those they cause) until the queue is empty.
 * Returns the number of frames delivered. */
uint32_t co_membus_deliver(co_membus_t *bus, int64_t now_us);

#endif /* CO_MEMBUS_H */

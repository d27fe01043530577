/* co_membus.c - in-process CAN bus (see co_membus.h). */
#include "co_membus.h"

#include <string.h>

void co_membus_init(co_membus_t *bus, co_membus_sink_fn sink, void *sink_user)
{
    memset(bus, 0, sizeof *bus);
    bus->sink = sink;
    bus->sink_user = sink_user;
}

int co_membus_port(co_membus_t *bus)
{
    if (bus->n_nodes >= CO_MEMBUS_NODES) return -1;
    int i = bus->n_nodes++;
    bus->ports[i].bus = bus;
    bus->ports[i].index = (uint8_t)i;
    bus->nodes[i] = NULL;
    return i;
}

void co_membus_attach(co_membus_t *bus, int port, co_node_t *node)
{
    if (port >= 0 && port < (int)bus->n_nodes) bus->nodes[port] = node;
}

static int enqueue(co_membus_t *bus, const co_frame_t *frame, uint8_t sender)
{
    if (bus->tail - bus->head >= CO_MEMBUS_QUEUE) {
        ++bus->overflows;
        return -1;
    }
    uint32_t slot = bus->tail % CO_MEMBUS_QUEUE;
    bus->queue[slot] = *frame;
    bus->sender[slot] = sender;
    ++bus->tail;
    return 0;
}

int co_membus_tx(void *user, const co_frame_t *frame)
{
    co_membus_port_t *port = (co_membus_port_t *)user;
    return enqueue(port->bus, frame, port->index);
}

int co_membus_inject(co_membus_t *bus, const co_frame_t *frame) { return enqueue(bus, frame, CO_MEMBUS_EXTERNAL); }

uint32_t co_membus_deliver(co_membus_t *bus, int64_t now_us)
{
    uint32_t n = 0;
    while (bus->head != bus->tail) {
        uint32_t slot = bus->head % CO_MEMBUS_QUEUE;
        co_frame_t f = bus->queue[slot];
        uint8_t sender = bus->sender[slot];
        ++bus->head;
        ++bus->frames;
        ++n;
        if (bus->sink) bus->sink(bus->sink_user, &f, sender, now_us);
        for (uint8_t i = 0; i < bus->n_nodes; ++i)
            if (i != sender && bus->nodes[i]) co_node_process(bus->nodes[i], &f, now_us);
    }
    return n;
}

/* Byte order helpers shared by the mesh and volume readers and writers. */
#ifndef ISOMEND_BYTE_ORDER_H
#define ISOMEND_BYTE_ORDER_H

#include <stdint.h>
#include <string.h>

static inline int machine_is_big_endian(void)
{
    const uint16_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 0;
}

/* Stores the 4 bytes at `v` at `p` little-endian (`p` may equal `v`). */
static inline void put_le32(unsigned char *p, const void *v)
{
    memcpy(p, v, 4);
    if (machine_is_big_endian()) {
        unsigned char t = p[0];
        p[0] = p[3];
        p[3] = t;
        t = p[1];
        p[1] = p[2];
        p[2] = t;
    }
}

#endif

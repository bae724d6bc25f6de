/*
 * host.c - isomend_host_reclaims_free_memory(): is this a virtual machine
 * whose kernel hands free memory back to its host?
 */
#include "host.h"
#include "isomend.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int isomend_host_reclaims_free_memory_at(const char *root)
{
    /* A virtio device of type 5 (memory balloon) that negotiated feature bit 5
     * (VIRTIO_BALLOON_F_REPORTING): the guest kernel reports free 2 MiB blocks,
     * and the host takes them back.  The features file has one character a
     * bit, bit 0 first. */
    char path[512], buf[160];
    for (int d = 0; d < 64; d++) {
        snprintf(path, sizeof path, "%s/sys/bus/virtio/devices/virtio%d/device", root, d);
        FILE *f = fopen(path, "r");
        if (!f)
            continue;
        const int balloon = fgets(buf, sizeof buf, f) && strtol(buf, NULL, 16) == 5;
        fclose(f);
        if (!balloon)
            continue;
        snprintf(path, sizeof path, "%s/sys/bus/virtio/devices/virtio%d/features", root, d);
        f = fopen(path, "r");
        if (!f)
            continue;
        const int reporting = fgets(buf, sizeof buf, f) && strlen(buf) > 5 && buf[5] == '1';
        fclose(f);
        if (reporting)
            return 1;
    }
    return 0;
}

int isomend_host_reclaims_free_memory(void)
{
#if defined(__linux__)
    return isomend_host_reclaims_free_memory_at("");
#else
    return 0;
#endif
}

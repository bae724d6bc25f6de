/*
 * test_host_memory.c - isomend_host_reclaims_free_memory() (libcore/src/host.c),
 * the test behind `isomend extract --pages auto` and the hosts' choice of small
 * pages: on fake sysfs trees, 1 only for a virtio memory balloon (device
 * 0x0005) whose negotiated features have bit 5 (VIRTIO_BALLOON_F_REPORTING)
 * set; then the answer for this machine, printed.
 */
#define _DEFAULT_SOURCE
#include "host.h"
#include "isomend.h"
#include "testutil.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char root[256];
static int ntrees;

/* A fresh tree with `n` virtio devices: types[i], features[i]. */
static void make_tree(int n, const int *ids, const char *const *types, const char *const *features)
{
    snprintf(root, sizeof root, "%s/tree%d", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", ntrees++);
    char path[512];
    const char *parts[] = {"", "/sys", "/sys/bus", "/sys/bus/virtio", "/sys/bus/virtio/devices"};
    for (int p = 0; p < 5; p++) {
        snprintf(path, sizeof path, "%s%s", root, parts[p]);
        (void)mkdir(path, 0700);
    }
    for (int i = 0; i < n; i++) {
        snprintf(path, sizeof path, "%s/sys/bus/virtio/devices/virtio%d", root, ids[i]);
        (void)mkdir(path, 0700);
        const char *names[2] = {"device", "features"};
        const char *text[2] = {types[i], features[i]};
        for (int f = 0; f < 2; f++) {
            snprintf(path, sizeof path, "%s/sys/bus/virtio/devices/virtio%d/%s", root, ids[i],
                     names[f]);
            FILE *fp = fopen(path, "w");
            CHECK(fp != NULL);
            if (fp) {
                fprintf(fp, "%s\n", text[f]);
                fclose(fp);
            }
        }
    }
}

int main(void)
{
    /* features as the kernel prints them: one character per bit, bit 0 first */
    const char *reporting = "0110010100000000000000000000000010000000";
    const char *no_reporting = "0110000100000000000000000000000010000000";

    make_tree(0, NULL, NULL, NULL); /* no virtio devices: bare metal */
    CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 0);

    {
        const int ids[] = {0};
        const char *t[] = {"0x0005"}, *f[] = {reporting};
        make_tree(1, ids, t, f);
        CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 1);
    }
    {
        const int ids[] = {0};
        const char *t[] = {"0x0005"}, *f[] = {no_reporting}; /* a balloon, no reporting */
        make_tree(1, ids, t, f);
        CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 0);
    }
    {
        const int ids[] = {0, 1};
        const char *t[] = {"0x0001", "0x0002"}, *f[] = {reporting, reporting}; /* net, block */
        make_tree(2, ids, t, f);
        CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 0);
    }
    {
        const int ids[] = {0, 7};
        const char *t[] = {"0x0001", "0x0005"}, *f[] = {no_reporting, reporting};
        make_tree(2, ids, t, f);
        CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 1);
    }
    {
        const int ids[] = {0};
        const char *t[] = {"0x0005"}, *f[] = {"0110"}; /* too short to have bit 5 */
        make_tree(1, ids, t, f);
        CHECK_EQ_INT(isomend_host_reclaims_free_memory_at(root), 0);
    }
    const int here = isomend_host_reclaims_free_memory();
    CHECK_EQ_INT(here, isomend_host_reclaims_free_memory_at(""));
    printf("this machine: the host takes free memory back: %s\n",
           here ? "yes (small pages for one-shot extractions)" : "no (huge pages)");
    TEST_EXIT();
}

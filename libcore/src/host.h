/*
 * host.h - what the library reads of the machine it runs on (host.c).
 */
#ifndef ISOMEND_HOST_H
#define ISOMEND_HOST_H

/* isomend_host_reclaims_free_memory() on the tree under `root` ("" in use, a
 * folder of fake sysfs files in tests). */
int isomend_host_reclaims_free_memory_at(const char *root);

#endif

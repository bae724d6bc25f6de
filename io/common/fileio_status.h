/*
 * fileio_status.h - what the file functions of io/common answer (internal):
 * a status, and the sizes of the message and path buffers they fill.  Types
 * only, shared by the volume readers, the atomic outputs and the mesh
 * writers and readers, so that none of them includes another for these.
 */
#ifndef ISOMEND_FILEIO_STATUS_H
#define ISOMEND_FILEIO_STATUS_H

typedef enum isomend_fileio_status {
    ISOMEND_FILEIO_OK = 0,
    ISOMEND_FILEIO_ERR_INVALID_ARGUMENT = 1, /* NULL, bad dims/type, buffer too small */
    ISOMEND_FILEIO_ERR_NOT_FOUND = 2,        /* the file (or data file) does not exist */
    ISOMEND_FILEIO_ERR_UNREADABLE = 3,       /* cannot open/read (permissions, I/O)    */
    ISOMEND_FILEIO_ERR_FORMAT = 4,           /* malformed header                       */
    ISOMEND_FILEIO_ERR_UNSUPPORTED = 5,      /* valid NRRD we do not read              */
    ISOMEND_FILEIO_ERR_SIZE = 6,             /* data size differs from the header/dims */
    ISOMEND_FILEIO_ERR_CORRUPT = 7,          /* corrupt compressed data                */
    ISOMEND_FILEIO_ERR_OUT_OF_MEMORY = 8,
    ISOMEND_FILEIO_ERR_WRITE = 9,            /* cannot write an output file            */
    ISOMEND_FILEIO_ERR_CANCELLED = 10        /* the progress callback asked to stop    */
} isomend_fileio_status;

/* Size of a message buffer that always holds a whole message. */
#define ISOMEND_FILEIO_MSG_SIZE 1280
#define ISOMEND_FILEIO_PATH_MAX 1024

#endif /* ISOMEND_FILEIO_STATUS_H */

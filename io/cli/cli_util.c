/*
 * cli_util.c - messages, strict number parsing, timing and the progress bar
 *
 * Numbers are parsed strictly (the whole argument must be the number, no
 * trailing text, finite) so that "--iso 1O" is a usage error naming the
 * flag instead of silently meaning 1.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

cli_progress *cli_active_progress;
volatile int cli_interrupted;

static void on_signal(int sig)
{
    (void)sig;
    cli_interrupted = 1;
}

void cli_install_signal_handlers(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    /* a file size limit (ulimit -f) is then a write error with a message and
     * no output, not a kill that leaves the temporary file behind */
    signal(SIGXFSZ, SIG_IGN);
}

const char *cli_program = "isomend";
static char *capture;
static size_t capture_size;

void cli_error_capture(char *buf, size_t size)
{
    capture = buf;
    capture_size = size;
    if (buf && size) buf[0] = '\0';
}

void cli_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (capture) { /* the first message is the one that matters */
        if (!capture[0]) vsnprintf(capture, capture_size, fmt, ap);
        va_end(ap);
        return;
    }
    if (cli_active_progress) cli_progress_clear(cli_active_progress);
    fprintf(stderr, "%s: ", cli_program);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

int cli_parse_double(const char *s, double *out)
{
    if (!s || !*s) return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno == ERANGE || !isfinite(v)) return 0;
    *out = v;
    return 1;
}

int cli_parse_int64(const char *s, int64_t *out)
{
    if (!s || !*s) return 0;
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (end == s || *end || errno == ERANGE) return 0;
    *out = v;
    return 1;
}

int cli_parse_doubles(const char *s, double *out, int n)
{
    char buf[512];
    if (!s || strlen(s) >= sizeof buf) return 0;
    strcpy(buf, s);
    char *p = buf;
    for (int i = 0; i < n; i++) {
        char *comma = strchr(p, ',');
        if (i < n - 1) {
            if (!comma) return 0;
            *comma = '\0';
        } else if (comma) {
            return 0;
        }
        if (!cli_parse_double(p, &out[i])) return 0;
        p = comma ? comma + 1 : p;
    }
    return 1;
}

int cli_parse_size(const char *s, uint64_t *out)
{
    if (!s || !*s || *s == '-' || *s == '+') return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno == ERANGE || !isfinite(v) || v < 0) return 0;
    double scale = 1;
    const char *units = "KMGT";
    if (*end) {
        const char *u = strchr(units, toupper((unsigned char)*end));
        if (!u) return 0;
        scale = ldexp(1.0, 10 * (int)(u - units + 1));
        end++;
        if (*end == 'i' && (end[1] == 'B' || end[1] == 'b')) end += 2; /* 4GiB */
        else if (*end == 'B' || *end == 'b') end++; /* 4GB means the same, binary */
    } else if (v != floor(v)) {
        return 0; /* a fraction of a byte */
    }
    if (*end) return 0;
    double bytes = floor(v * scale);
    if (!(bytes < 18446744073709551616.0)) return 0;
    *out = (uint64_t)bytes;
    return 1;
}

const char *cli_bytes_text(uint64_t bytes, char *buf, size_t size)
{
    double b = (double)bytes;
    if (b >= 1024.0 * 1024.0 * 1024.0)
        snprintf(buf, size, "%.2f GiB", b / (1024.0 * 1024.0 * 1024.0));
    else
        snprintf(buf, size, "%.1f MiB", b / (1024.0 * 1024.0));
    return buf;
}

uint64_t cli_proc_kib(const char *path, const char *key)
{
    FILE *fp = fopen(path, "r");
    if (!fp) return 0;
    char line[256];
    size_t n = strlen(key);
    unsigned long long kib = 0;
    while (fgets(line, sizeof line, fp))
        if (strncmp(line, key, n) == 0 && sscanf(line + n, " %llu kB", &kib) == 1) break;
    fclose(fp);
    return (uint64_t)kib;
}

uint64_t cli_memory_available(void)
{
    return cli_proc_kib("/proc/meminfo", "MemAvailable:") * 1024u;
}

double cli_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

void cli_progress_init(cli_progress *p, int enabled)
{
    memset(p, 0, sizeof *p);
    p->enabled = enabled;
    p->last_permille = -1;
}

void cli_progress_update(cli_progress *p, const char *label, double fraction)
{
    if (!p || !p->enabled) return;
    if (fraction < 0) fraction = 0;
    if (fraction > 1) fraction = 1;
    int permille = (int)(fraction * 1000.0);
    if (p->shown && label == p->label && permille / 10 == p->last_permille / 10) return;
    p->label = label;
    p->last_permille = permille;
    enum { WIDTH = 30 };
    char bar[WIDTH + 1];
    int fill = (int)(fraction * WIDTH);
    for (int i = 0; i < WIDTH; i++) bar[i] = i < fill ? '#' : '-';
    bar[WIDTH] = '\0';
    fprintf(stderr, "\r\033[K%-8s [%s] %3d%%", label, bar, permille / 10);
    fflush(stderr);
    p->shown = 1;
}

void cli_progress_clear(cli_progress *p)
{
    if (!p || !p->shown) return;
    fputs("\r\033[K", stderr);
    fflush(stderr);
    p->shown = 0;
}

int cli_progress_extract_cb(void *user, double fraction)
{
    cli_progress_update(user, "extract", fraction);
    return cli_interrupted;
}

int cli_progress_read_cb(void *user, double fraction)
{
    cli_progress_update(user, "read", fraction);
    return cli_interrupted;
}

void cli_json_string(FILE *fp, const char *s)
{
    fputc('"', fp);
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\')
            fprintf(fp, "\\%c", *p);
        else if (*p < 0x20)
            fprintf(fp, "\\u%04x", *p);
        else
            fputc(*p, fp);
    }
    fputc('"', fp);
}

int cli_extract_status(isomend_status st, const char *label, const char *what)
{
    if (st == ISOMEND_OK) return CLI_EXIT_OK;
    if (st == ISOMEND_ERR_CANCELLED) {
        cli_error("%s: interrupted", label);
        return CLI_EXIT_INTERRUPTED;
    }
    cli_error("%s: %s failed: %s", label, what, isomend_status_string(st));
    return CLI_EXIT_FAIL;
}

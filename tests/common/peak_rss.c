/*
 * peak_rss - runs a command and reports its peak resident memory.
 *
 *   peak_rss FILE COMMAND [ARG...]
 *
 * Runs COMMAND (stdin, stdout and stderr inherited), writes its peak
 * resident set in bytes (wait4's ru_maxrss) to FILE and exits with its exit
 * status (128 + the signal when killed).  A small C launcher, because Linux
 * carries the high-water mark of a process's memory across exec: a child
 * forked from a Python test would report the Python interpreter's peak.
 */
#define _DEFAULT_SOURCE
#include <stdio.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: peak_rss FILE COMMAND [ARG...]\n");
        return 2;
    }
    pid_t pid = fork();
    if (pid < 0) {
        perror("peak_rss: fork");
        return 2;
    }
    if (pid == 0) {
        execvp(argv[2], argv + 2);
        perror(argv[2]);
        _exit(127);
    }
    int status = 0;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) != pid) {
        perror("peak_rss: wait4");
        return 2;
    }
    FILE *f = fopen(argv[1], "w");
    if (!f || fprintf(f, "%ld\n", ru.ru_maxrss * 1024L) < 0 || fclose(f) != 0) {
        perror(argv[1]);
        return 2;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

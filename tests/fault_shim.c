/* Fault injection at the write layer, for tests/test_write_faults.py (loaded with LD_PRELOAD).
 *
 * Counts the calls that write to files under the directory FAULT_DIR (write, pwrite, pwrite64,
 * fsync, fdatasync, rename, renameat: the calls through which HDF5, the sample journal and the
 * atomic renames reach the disk) and, from call number FAULT_AT on (1-based), fails them with
 * FAULT_ERRNO (default ENOSPC), as a disk that has just filled up would. FAULT_AT=0 fails
 * nothing. With FAULT_LOG set, each counted call appends "<number> <call> <path>" to that file,
 * so a test can pick the first write, a middle one, the last one and the final rename of a run.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

typedef ssize_t (*write_fn)(int, const void *, size_t);
typedef ssize_t (*pwrite_fn)(int, const void *, size_t, off_t);
typedef int (*sync_fn)(int);
typedef int (*rename_fn)(const char *, const char *);
typedef int (*renameat_fn)(int, const char *, int, const char *);

static long calls = 0;
static long fail_at = -1;
static int fail_errno = ENOSPC;
static char dir[4096] = "";
static size_t dir_len = 0;
static char fd_target[4096];

static void setup(void) {
    if (fail_at >= 0) return;
    const char *d = getenv("FAULT_DIR");
    const char *at = getenv("FAULT_AT");
    const char *code = getenv("FAULT_ERRNO");
    fail_at = at ? atol(at) : 0;
    if (code) fail_errno = atoi(code);
    if (d) {
        strncpy(dir, d, sizeof dir - 1);
        dir_len = strlen(dir);
    }
}

static int under_dir(const char *path) {
    return dir_len && path && strncmp(path, dir, dir_len) == 0;
}

static int fd_under_dir(int fd) {
    char link[64];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = readlink(link, fd_target, sizeof fd_target - 1);
    if (n <= 0) return 0;
    fd_target[n] = '\0';
    return under_dir(fd_target);
}

/* The log lies outside FAULT_DIR, so its own writes are never counted. */
static void log_call(const char *call, const char *path) {
    const char *log = getenv("FAULT_LOG");
    if (!log) return;
    FILE *f = fopen(log, "a");
    if (f) {
        fprintf(f, "%ld %s %s\n", calls, call, path);
        fclose(f);
    }
}

/* 1 when this call must fail (errno is then set). */
static int inject(int counted, const char *call, const char *path) {
    if (!counted) return 0;
    calls++;
    log_call(call, path);
    if (fail_at > 0 && calls >= fail_at) {
        errno = fail_errno;
        return 1;
    }
    return 0;
}

#define REAL(type, name) \
    static type real_##name = NULL; \
    if (!real_##name) real_##name = (type)dlsym(RTLD_NEXT, #name)

ssize_t write(int fd, const void *buf, size_t count) {
    REAL(write_fn, write);
    setup();
    if (fd > 2 && inject(fd_under_dir(fd), "write", fd_target)) return -1;
    return real_write(fd, buf, count);
}

ssize_t pwrite(int fd, const void *buf, size_t count, off_t offset) {
    REAL(pwrite_fn, pwrite);
    setup();
    if (inject(fd_under_dir(fd), "pwrite", fd_target)) return -1;
    return real_pwrite(fd, buf, count, offset);
}

ssize_t pwrite64(int fd, const void *buf, size_t count, off_t offset) {
    REAL(pwrite_fn, pwrite64);
    setup();
    if (inject(fd_under_dir(fd), "pwrite64", fd_target)) return -1;
    return real_pwrite64(fd, buf, count, offset);
}

int fsync(int fd) {
    REAL(sync_fn, fsync);
    setup();
    if (inject(fd_under_dir(fd), "fsync", fd_target)) return -1;
    return real_fsync(fd);
}

int fdatasync(int fd) {
    REAL(sync_fn, fdatasync);
    setup();
    if (inject(fd_under_dir(fd), "fdatasync", fd_target)) return -1;
    return real_fdatasync(fd);
}

int rename(const char *old, const char *new) {
    REAL(rename_fn, rename);
    setup();
    if (inject(under_dir(new), "rename", new)) return -1;
    return real_rename(old, new);
}

int renameat(int olddirfd, const char *old, int newdirfd, const char *new) {
    REAL(renameat_fn, renameat);
    setup();
    if (inject(under_dir(new), "renameat", new)) return -1;
    return real_renameat(olddirfd, old, newdirfd, new);
}

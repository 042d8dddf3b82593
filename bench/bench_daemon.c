/* bench_daemon — scicapd on the simulated bench (256×256×8, embedded default scene), through its socket:
 *   1. sustained snapshots per second for a 40-snapshot capture job, without and with a GAP-TV reconstruction
 *      (fast preset, 1 worker) queued for every snapshot;
 *   2. daemon CPU time per snapshot over each run (/proc/<pid>/stat utime + stime);
 *   3. latency from the capture request to the "capture.stored" event, one snapshot at a time (median, p90).
 * Storage is a temporary folder with fsync on (the service default). Writes bench/results/daemon.md. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <jansson.h>
#include <libgen.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/store.h"

static int sock_fd = -1;
static char rbuf[1 << 16];
static size_t rlen;

static json_t *read_msg(int timeout_ms)
{
    int64_t t0 = sci_clock_mono_ns();
    for (;;) {
        char *nl = memchr(rbuf, '\n', rlen);
        if (nl) {
            size_t n = (size_t)(nl - rbuf);
            json_t *m = json_loadb(rbuf, n, 0, NULL);
            memmove(rbuf, nl + 1, rlen - n - 1);
            rlen -= n + 1;
            return m;
        }
        int left = timeout_ms - (int)((sci_clock_mono_ns() - t0) / 1000000);
        struct pollfd p = {.fd = sock_fd, .events = POLLIN};
        if (left <= 0 || poll(&p, 1, left) <= 0)
            return NULL;
        ssize_t r = recv(sock_fd, rbuf + rlen, sizeof rbuf - rlen, 0);
        if (r <= 0)
            return NULL;
        rlen += (size_t)r;
    }
}

static int send_req(const char *line)
{
    return send(sock_fd, line, strlen(line), MSG_NOSIGNAL) == (ssize_t)strlen(line) ? 0 : -1;
}

/* Wait for event `name`; counts other events named `count_name` into *counted. NULL on timeout. */
static json_t *wait_event(const char *name, int timeout_ms)
{
    for (;;) {
        json_t *m = read_msg(timeout_ms);
        if (!m)
            return NULL;
        const char *ev = json_string_value(json_object_get(m, "event"));
        if (ev && !strcmp(ev, name))
            return m;
        if (ev && strstr(ev, ".failed")) {
            char *s = json_dumps(m, JSON_COMPACT);
            fprintf(stderr, "bench_daemon: %s\n", s);
            free(s);
            json_decref(m);
            return NULL;
        }
        json_decref(m);
    }
}

static double proc_cpu_s(pid_t pid)
{
    char p[64], buf[2048];
    snprintf(p, sizeof p, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(p, "r");
    if (!f)
        return NAN;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    char *s = strrchr(buf, ')');
    unsigned long ut = 0, st = 0;
    if (!s || sscanf(s + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st) != 2)
        return NAN;
    return (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

typedef struct run_result {
    double per_s, cpu_per_snap_ms, recon_psnr;
    int snapshots, recons;
} run_result;

static int sustained(pid_t pid, int count, int recon, run_result *out)
{
    char line[256];
    snprintf(line, sizeof line,
             "{\"v\":1,\"id\":1,\"cmd\":\"capture\",\"args\":{\"count\":%d,\"reconstruct\":%s,\"preset\":\"fast\"}}\n",
             count, recon ? "true" : "false");
    double cpu0 = proc_cpu_s(pid);
    int64_t t0 = sci_clock_mono_ns(), t_first = 0, t_last = 0;
    if (send_req(line) < 0)
        return -1;
    int stored = 0, recons = 0;
    double psnr = NAN;
    while (stored < count || (recon && recons < count)) {
        json_t *m = read_msg(120000);
        if (!m)
            return -1;
        const char *ev = json_string_value(json_object_get(m, "event"));
        if (ev && !strcmp(ev, "capture.stored")) {
            stored++;
            t_last = sci_clock_mono_ns();
            if (!t_first)
                t_first = t_last;
        } else if (ev && !strcmp(ev, "recon.done")) {
            recons++;
            psnr = json_number_value(json_object_get(json_object_get(m, "data"), "psnr"));
        } else if (ev && (strstr(ev, ".failed") || strstr(ev, ".rejected"))) {
            char *s = json_dumps(m, JSON_COMPACT);
            fprintf(stderr, "bench_daemon: %s\n", s);
            free(s);
            json_decref(m);
            return -1;
        }
        json_decref(m);
    }
    double cpu1 = proc_cpu_s(pid);
    (void)t0;
    out->snapshots = stored;
    out->recons = recons;
    out->per_s = (stored - 1) / sci_clock_s(t_first, t_last);
    out->cpu_per_snap_ms = (cpu1 - cpu0) * 1e3 / stored;
    out->recon_psnr = psnr;
    return 0;
}

int main(void)
{
    char self[1024], bin[1200], dir[] = "/tmp/scicap-bench-daemon-XXXXXX";
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return 1;
    self[n] = '\0';
    snprintf(bin, sizeof bin, "%s/../scicapd", dirname(self));
    if (!mkdtemp(dir))
        return 1;
    char sockp[200], store[200], run[200], logp[200];
    snprintf(sockp, sizeof sockp, "%s/control.sock", dir);
    snprintf(store, sizeof store, "%s/store", dir);
    snprintf(run, sizeof run, "%s/run", dir);
    snprintf(logp, sizeof logp, "%s/scicapd.log", dir);
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(logp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 2);
        execl(bin, bin, "--no-config", "--socket", sockp, "--storage", store, "--runtime-dir", run, (char *)NULL);
        _exit(127);
    }
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", sockp);
    for (int i = 0; i < 200 && sock_fd < 0; i++) {
        int fd = socket(AF_UNIX, SOCK_STREAM, 0);
        if (connect(fd, (struct sockaddr *)&sa, sizeof sa) == 0)
            sock_fd = fd;
        else {
            close(fd);
            usleep(50000);
        }
    }
    int status = 1;
    if (sock_fd < 0) {
        fprintf(stderr, "bench_daemon: scicapd did not start (%s)\n", logp);
        goto out;
    }
    /* warm-up: masks generated and uploaded, scene rendered */
    send_req("{\"v\":1,\"id\":0,\"cmd\":\"capture\"}\n");
    json_decref(wait_event("capture.done", 60000));
    run_result plain, with_recon;
    if (sustained(pid, 40, 0, &plain) < 0 || sustained(pid, 40, 1, &with_recon) < 0) {
        fprintf(stderr, "bench_daemon: run failed (log %s)\n", logp);
        goto out;
    }
    enum { LAT = 15 };
    double lat[LAT];
    for (int i = 0; i < LAT; i++) {
        int64_t t0 = sci_clock_mono_ns();
        send_req("{\"v\":1,\"id\":2,\"cmd\":\"capture\"}\n");
        json_t *m = wait_event("capture.stored", 30000);
        if (!m)
            goto out;
        lat[i] = (double)(sci_clock_mono_ns() - t0) * 1e-6;
        json_decref(m);
        json_decref(wait_event("capture.done", 30000));
    }
    qsort(lat, LAT, sizeof lat[0], cmp_double);
    printf("snapshots/s (capture + store only):      %.1f  (%d snapshots)\n", plain.per_s, plain.snapshots);
    printf("snapshots/s (+ GAP-TV fast per snapshot): %.1f  (%d reconstructions, last PSNR %.2f dB)\n",
           with_recon.per_s, with_recon.recons, with_recon.recon_psnr);
    printf("daemon CPU per snapshot: %.0f ms (capture + store), %.0f ms (with its reconstruction)\n",
           plain.cpu_per_snap_ms, with_recon.cpu_per_snap_ms);
    printf("request -> stored latency: median %.0f ms, p90 %.0f ms, min %.0f ms (%d single-snapshot requests)\n",
           lat[LAT / 2], lat[(LAT * 9) / 10], lat[0], LAT);
    mkdir("bench/results", 0755);
    FILE *f = fopen("bench/results/daemon.md", "w");
    if (f) {
        fprintf(f, "| scicapd, simulated bench 256×256×8, fsync on (2 shared cores) | value |\n|---|---|\n");
        fprintf(f, "| sustained snapshots/s, capture + store | %.1f |\n", plain.per_s);
        fprintf(f, "| sustained snapshots/s, with a GAP-TV (fast, 30 it.) reconstruction per snapshot alongside | %.1f |\n",
                with_recon.per_s);
        fprintf(f, "| daemon CPU per snapshot, capture + store | %.0f ms |\n", plain.cpu_per_snap_ms);
        fprintf(f, "| daemon CPU per snapshot, including its reconstruction | %.0f ms |\n", with_recon.cpu_per_snap_ms);
        fprintf(f, "| capture request → stored snapshot, median / p90 | %.0f / %.0f ms |\n", lat[LAT / 2],
                lat[(LAT * 9) / 10]);
        fclose(f);
    }
    status = 0;
out:
    if (pid > 0) {
        kill(pid, SIGTERM);
        waitpid(pid, NULL, 0);
    }
    scicapd_remove_tree(dir);
    return status;
}

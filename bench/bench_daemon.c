/* bench_daemon — scicapd on the simulated bench (256×256×8, embedded default scene), through its socket, for
 * three storage settings (storage.writers 1 and 2 with previews, 2 without previews; reconstruction workers and
 * threads at their defaults):
 *   1. sustained snapshots per second for a 40-snapshot capture job (--snapshots), without and with a GAP-TV
 *      reconstruction (fast preset) requested for every snapshot; with reconstructions, the rate at which they
 *      were done too (over the whole run and over its second half), and how many were refused (none since the
 *      reconstruction queue applies back-pressure: the bench fails if any is);
 *   2. daemon CPU time per snapshot over each run (/proc/<pid>/stat utime + stime), and where it went: the
 *      daemon's per-stage counters (status "timing": acquire, store, recon read/solve/write, thread CPU);
 *   3. latency from the capture request to the "capture.stored" event, one snapshot at a time (median, p90).
 * Storage is a temporary folder with fsync on (the service default). Writes bench/results/daemon.md with the
 * 1-minute load average beside every figure (2 shared cores: figures are noisy).
 *
 *     bench_daemon [--snapshots N] [--latency N] [--settings writers1,writers2,writers2-nopreviews] [--out FILE|-]
 *
 * --snapshots: per sustained run (default 40); --latency: single captures timed (default 15); --settings: which
 * columns (default all three); --out: the table's file (default bench/results/daemon.md, "-": none) — a quick
 * check that the bench works (--snapshots 4 --latency 3 --out -) then records nothing. */
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
#include "base/runtime_env.h"
#include "io/staging.h"

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
    double per_s, recon_per_s, cpu_per_snap_ms, recon_psnr, load;
    double steady_per_s, steady_recon_per_s; /* over the second half of each kind of event (see half_rate) */
    int snapshots, recons, rejected;
    double stage_cpu_ms[5], stage_wall_ms[5]; /* per stage run during this measurement */
} run_result;

static const char *const stages[5] = {"acquire", "store", "recon_read", "recon_solve", "recon_write"};

/* The daemon's stage counters (status "timing"): totals per stage into cpu_s/wall_s/count. */
static int timing_read(double cpu_s[5], double wall_s[5], long long count[5])
{
    if (send_req("{\"v\":1,\"id\":9,\"cmd\":\"status\"}\n") < 0)
        return -1;
    for (;;) {
        json_t *m = read_msg(30000);
        if (!m)
            return -1;
        json_t *id = json_object_get(m, "id");
        if (json_is_integer(id) && json_integer_value(id) == 9) {
            json_t *t = json_object_get(json_object_get(m, "result"), "timing");
            for (int i = 0; i < 5; i++) {
                json_t *o = json_object_get(t, stages[i]);
                cpu_s[i] = json_number_value(json_object_get(o, "cpu_s_total"));
                wall_s[i] = json_number_value(json_object_get(o, "wall_s_total"));
                count[i] = json_integer_value(json_object_get(o, "count"));
            }
            json_decref(m);
            return t ? 0 : -1;
        }
        json_decref(m);
    }
}

/* Events per second over the second half of n event times: with a reconstruction per snapshot the first captures
 * run ahead while the reconstruction queue (16 deep) fills, so the whole-run rates mix that start with the pace
 * the two settle to; the second half is nearer the sustained rates. NAN below 10 events (two writers finish in
 * pairs: fewer give nonsense). */
static double half_rate(const int64_t *t, int n)
{
    const int h = n / 2;
    return n >= 10 && t[n - 1] > t[h] ? (double)(n - 1 - h) / sci_clock_s(t[h], t[n - 1]) : NAN;
}

static int sustained(pid_t pid, int count, int recon, run_result *out)
{
    enum { MAX_EVENTS = 1000 };
    int64_t t_stored[MAX_EVENTS], t_recon[MAX_EVENTS];
    char line[256];
    snprintf(line, sizeof line,
             "{\"v\":1,\"id\":1,\"cmd\":\"capture\",\"args\":{\"count\":%d,\"reconstruct\":%s,\"preset\":\"fast\"}}\n",
             count, recon ? "true" : "false");
    double tc0[5], tw0[5], tc1[5], tw1[5];
    long long n0[5], n1[5];
    if (timing_read(tc0, tw0, n0) < 0)
        return -1;
    double cpu0 = proc_cpu_s(pid);
    int64_t t0 = sci_clock_mono_ns(), t_first = 0, t_last = 0, r_first = 0, r_last = 0;
    if (send_req(line) < 0)
        return -1;
    int stored = 0, recons = 0, rejected = 0;
    double psnr = NAN;
    while (stored < count || (recon && recons + rejected < count)) {
        json_t *m = read_msg(120000);
        if (!m)
            return -1;
        const char *ev = json_string_value(json_object_get(m, "event"));
        if (ev && !strcmp(ev, "capture.stored")) {
            t_last = sci_clock_mono_ns();
            if (stored < MAX_EVENTS)
                t_stored[stored] = t_last;
            stored++;
            if (!t_first)
                t_first = t_last;
        } else if (ev && !strcmp(ev, "recon.done")) {
            r_last = sci_clock_mono_ns();
            if (recons < MAX_EVENTS)
                t_recon[recons] = r_last;
            recons++;
            if (!r_first)
                r_first = r_last;
            psnr = json_number_value(json_object_get(json_object_get(m, "data"), "psnr"));
        } else if (ev && !strcmp(ev, "recon.rejected")) {
            rejected++; /* reconstruction queue full: reported, the capture went on */
        } else if (ev && strstr(ev, ".failed")) {
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
    if (timing_read(tc1, tw1, n1) < 0)
        return -1;
    for (int i = 0; i < 5; i++) {
        long long n = n1[i] - n0[i];
        out->stage_cpu_ms[i] = n > 0 ? (tc1[i] - tc0[i]) * 1e3 / (double)n : 0;
        out->stage_wall_ms[i] = n > 0 ? (tw1[i] - tw0[i]) * 1e3 / (double)n : 0;
    }
    double la[1] = {NAN};
    getloadavg(la, 1);
    out->load = la[0];
    out->recon_per_s = recons > 1 ? (recons - 1) / sci_clock_s(r_first, r_last) : NAN;
    out->snapshots = stored;
    out->recons = recons;
    out->rejected = rejected;
    out->per_s = (stored - 1) / sci_clock_s(t_first, t_last);
    out->steady_per_s = half_rate(t_stored, stored < MAX_EVENTS ? stored : MAX_EVENTS);
    out->steady_recon_per_s = half_rate(t_recon, recons < MAX_EVENTS ? recons : MAX_EVENTS);
    out->cpu_per_snap_ms = (cpu1 - cpu0) * 1e3 / stored;
    out->recon_psnr = psnr;
    return 0;
}

typedef struct setting {
    const char *name, *config;
    run_result plain, with_recon;
    double lat_median, lat_p90, lat_load;
    int ok;
} setting;

typedef struct bench_opts {
    int snapshots, latency;
    const char *settings, *out;
} bench_opts;

/* One daemon with `config` (JSON text), measured; 0 on success. */
static int measure(setting *st, const char *bin, const char *dir, const bench_opts *bo)
{
    char sockp[200], store[200], run[200], logp[200], cfgp[200];
    snprintf(sockp, sizeof sockp, "%s/control.sock", dir);
    snprintf(store, sizeof store, "%s/store-%s", dir, st->name);
    snprintf(run, sizeof run, "%s/run", dir);
    snprintf(logp, sizeof logp, "%s/scicapd-%s.log", dir, st->name);
    snprintf(cfgp, sizeof cfgp, "%s/%s.json", dir, st->name);
    FILE *cf = fopen(cfgp, "w");
    if (!cf)
        return -1;
    fputs(st->config, cf);
    fclose(cf);
    unlink(sockp);
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(logp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 2);
        execl(bin, bin, "--config", cfgp, "--socket", sockp, "--storage", store, "--runtime-dir", run,
              geteuid() == 0 ? "--allow-root" : (char *)NULL, (char *)NULL);
        _exit(127);
    }
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", sockp);
    sock_fd = -1;
    rlen = 0;
    for (int i = 0; i < 200 && sock_fd < 0; i++) {
        int fd = socket(AF_UNIX, SOCK_STREAM, 0);
        if (connect(fd, (struct sockaddr *)&sa, sizeof sa) == 0)
            sock_fd = fd;
        else {
            close(fd);
            usleep(50000);
        }
    }
    int status = -1;
    if (sock_fd < 0) {
        fprintf(stderr, "bench_daemon: scicapd did not start (%s)\n", logp);
        goto out;
    }
    /* warm-up: masks generated and uploaded, scene rendered */
    send_req("{\"v\":1,\"id\":0,\"cmd\":\"capture\"}\n");
    json_decref(wait_event("capture.done", 60000));
    if (sustained(pid, bo->snapshots, 0, &st->plain) < 0 || sustained(pid, bo->snapshots, 1, &st->with_recon) < 0) {
        fprintf(stderr, "bench_daemon: run failed (log %s)\n", logp);
        goto out;
    }
    enum { LAT_MAX = 100 };
    const int LAT = bo->latency;
    double lat[LAT_MAX];
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
    st->lat_median = lat[LAT / 2];
    st->lat_p90 = lat[(LAT * 9) / 10];
    getloadavg(&st->lat_load, 1);
    st->ok = 1;
    status = 0;
    printf("[%s]\n", st->name);
    printf("  snapshots/s (capture + store only):      %.1f  (%d snapshots)\n", st->plain.per_s, st->plain.snapshots);
    printf("  snapshots/s (+ GAP-TV fast per snapshot): %.1f captured, %.1f reconstructed  (%d reconstructed, "
           "%d refused)\n", st->with_recon.per_s, st->with_recon.recon_per_s, st->with_recon.recons,
           st->with_recon.rejected);
    printf("  second half of that run's events: %.1f captured, %.1f reconstructed per s\n",
           st->with_recon.steady_per_s, st->with_recon.steady_recon_per_s);
    printf("  per snapshot, thread CPU / wall ms:");
    for (int i = 0; i < 5; i++)
        printf(" %s %.0f/%.0f", stages[i], st->with_recon.stage_cpu_ms[i], st->with_recon.stage_wall_ms[i]);
    printf("\n");
    printf("  daemon CPU per snapshot: %.0f ms (capture + store), %.0f ms (with reconstructions)\n",
           st->plain.cpu_per_snap_ms, st->with_recon.cpu_per_snap_ms);
    printf("  request -> stored latency: median %.0f ms, p90 %.0f ms\n", st->lat_median, st->lat_p90);
out:
    if (sock_fd >= 0)
        close(sock_fd);
    if (pid > 0) {
        kill(pid, SIGTERM);
        waitpid(pid, NULL, 0);
    }
    return status;
}

static int usage(void)
{
    fprintf(stderr, "usage: bench_daemon [--snapshots N (2..1000)] [--latency N (1..100)] [--settings a,b,...] "
                    "[--out FILE|-]\n");
    return 2;
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    bench_opts bo = {.snapshots = 40, .latency = 15, .settings = NULL, .out = "bench/results/daemon.md"};
    for (int i = 1; i < argc; i++) {
        if (i + 1 >= argc)
            return usage();
        if (!strcmp(argv[i], "--snapshots"))
            bo.snapshots = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--latency"))
            bo.latency = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--settings"))
            bo.settings = argv[++i];
        else if (!strcmp(argv[i], "--out"))
            bo.out = argv[++i];
        else
            return usage();
    }
    if (bo.snapshots < 2 || bo.snapshots > 1000 /* MAX_EVENTS */ || bo.latency < 1 || bo.latency > 100)
        return usage();
    char self[1024], bin[1200], dir[] = "/tmp/scicap-bench-daemon-XXXXXX";
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return 1;
    self[n] = '\0';
    snprintf(bin, sizeof bin, "%s/../scicapd", dirname(self));
    if (!mkdtemp(dir))
        return 1;
    setting s[] = {
        {.name = "writers1", .config = "{\"storage\": {\"writers\": 1, \"previews\": true}}"},
        {.name = "writers2", .config = "{\"storage\": {\"writers\": 2, \"previews\": true}}"},
        {.name = "writers2-nopreviews", .config = "{\"storage\": {\"writers\": 2, \"previews\": false}}"},
    };
    enum { NS = sizeof s / sizeof s[0] };
    double load0[3] = {0}, load1[3] = {0};
    getloadavg(load0, 3);
    int status = 0;
    int chosen[NS], nchosen = 0;
    for (int i = 0; i < NS; i++) {
        chosen[i] = 1;
        if (bo.settings) { /* a name in the comma list, whole */
            const size_t l = strlen(s[i].name);
            const char *p = bo.settings;
            chosen[i] = 0;
            while ((p = strstr(p, s[i].name))) {
                if ((p == bo.settings || p[-1] == ',') && (p[l] == ',' || p[l] == '\0'))
                    chosen[i] = 1;
                p += l;
            }
        }
        nchosen += chosen[i];
    }
    if (!nchosen)
        return usage();
    for (int i = 0; i < NS; i++)
        if (chosen[i] && measure(&s[i], bin, dir, &bo) < 0)
            status = 1;
    getloadavg(load1, 3);
    printf("load average before %.2f, after %.2f (1 min)\n", load0[0], load1[0]);
    for (int i = 0; i < NS; i++)
        if (s[i].ok && s[i].with_recon.rejected > 0) {
            fprintf(stderr, "bench_daemon: %s: %d reconstructions refused\n", s[i].name, s[i].with_recon.rejected);
            status = 1;
        }
    if (status == 0 && nchosen < NS && strcmp(bo.out, "-") != 0)
        printf("bench_daemon: %d of %d settings measured: %s not written (the table has every column)\n", nchosen,
               NS, bo.out);
    if (status == 0 && nchosen == NS && strcmp(bo.out, "-") != 0) {
        if (!strcmp(bo.out, "bench/results/daemon.md"))
            mkdir("bench/results", 0755);
        FILE *f = fopen(bo.out, "w");
        if (f) {
            fprintf(f, "| scicapd, simulated bench 256×256×8, fsync on, 2 shared cores (load: 1-min average at the "
                       "end of each run; %.1f before, %.1f after) | writers 1 | writers 2 (default) | writers 2, no "
                       "previews |\n|---|---|---|---|\n", load0[0], load1[0]);
            fprintf(f, "| sustained snapshots/s, capture + store |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.1f (load %.1f) |", s[i].plain.per_s, s[i].plain.load);
            fprintf(f, "\n| with a GAP-TV (fast, 30 it.) reconstruction requested per snapshot: snapshots/s "
                       "captured / reconstructed |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.1f / %.1f (load %.1f) |", s[i].with_recon.per_s, s[i].with_recon.recon_per_s,
                        s[i].with_recon.load);
            fprintf(f, "\n| the same over the second half of each kind of event (the first captures run ahead while "
                       "the reconstruction queue fills): captured / reconstructed per s |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.1f / %.1f |", s[i].with_recon.steady_per_s, s[i].with_recon.steady_recon_per_s);
            fprintf(f, "\n| of those %d: reconstructed / refused |", bo.snapshots);
            for (int i = 0; i < NS; i++)
                fprintf(f, " %d / %d |", s[i].with_recon.recons, s[i].with_recon.rejected);
            fprintf(f, "\n| per snapshot with reconstruction, CPU ms of the stage's thread (OpenEXR's pool is off in "
                       "scicapd: compression is counted): acquire / store / recon read / solve / write |");
            for (int i = 0; i < NS; i++) {
                const double *c = s[i].with_recon.stage_cpu_ms;
                fprintf(f, " %.0f / %.0f / %.0f / %.0f / %.0f |", c[0], c[1], c[2], c[3], c[4]);
            }
            fprintf(f, "\n| daemon CPU per snapshot, capture + store |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.0f ms (load %.1f) |", s[i].plain.cpu_per_snap_ms, s[i].plain.load);
            fprintf(f, "\n| daemon CPU per snapshot, including reconstructions |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.0f ms (load %.1f) |", s[i].with_recon.cpu_per_snap_ms, s[i].with_recon.load);
            fprintf(f, "\n| capture request → stored snapshot, median / p90 |");
            for (int i = 0; i < NS; i++)
                fprintf(f, " %.0f / %.0f ms (load %.1f) |", s[i].lat_median, s[i].lat_p90, s[i].lat_load);
            fprintf(f, "\n");
            fclose(f);
        }
    }
    sci_staging_remove(dir);
    return status;
}

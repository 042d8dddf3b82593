/* scicapd — the acquisition-and-reconstruction daemon (docs/man/scicapd.8).
 *
 * The daemon's life, in order: options; log; scicapd_new (configuration, storage and its recovery, queues,
 * signals, devices, control socket, threads — each undone in reverse by scicapd_free); READY=1 once the socket
 * accepts connections; the event loop until SIGTERM/SIGINT or "shutdown"; STOPPING=1 and teardown.
 *
 * Root: the daemon needs no privilege (udev gives group scicap the devices, systemd/70-scicap.rules), so uid 0
 * is refused unless systemd started it (the unit decides, e.g. an override with User=root) or --allow-root says
 * the operator means it. systemd is recognised by $INVOCATION_ID, which it sets for every unit it starts (v232+);
 * a shell, sudo, cron or a container entry point do not set it. The check guards against a careless start,
 * not against someone who sets the variable by hand. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/log.h"
#include "base/runtime_env.h"
#include "daemon/config.h"
#include "daemon/daemon.h"
#include "daemon/udev_rules.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: scicapd [OPTIONS]\n"
            "\n"
            "The scicap acquisition-and-reconstruction daemon: owns the DMD, camera and trigger, takes requests on\n"
            "a Unix socket (newline-delimited JSON, docs/protocol.md), captures, reconstructs and stores.\n"
            "With no configuration file it runs the simulated bench with the embedded default scene.\n"
            "\n"
            "  -c, --config FILE      configuration (default " SCICAPD_CONFIG_DEFAULT_PATH " if it exists)\n"
            "      --no-config        ignore the default file: built-in defaults only\n"
            "  -s, --socket PATH      control socket (overrides control.socket)\n"
            "  -d, --storage DIR      storage root (overrides storage.root)\n"
            "  -r, --runtime-dir DIR  runtime folder (overrides storage.runtime_dir)\n"
            "      --no-fsync         do not fsync capture folders (tests, benchmarks on tmpfs)\n"
            "      --allow-root       run as uid 0 outside systemd (refused otherwise)\n"
            "  -v, --verbose          debug messages\n"
            "  -t, --check-config     validate the configuration and exit (0 valid, 1 invalid)\n"
            "      --udev-rules       print udev rules giving group scicap exactly the configured devices, exit\n"
            "  -h, --help             this text\n"
            "      --version          print the version\n");
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv);
    static const struct option opts[] = {
        {"config", required_argument, 0, 'c'}, {"no-config", no_argument, 0, 'N'},
        {"socket", required_argument, 0, 's'}, {"storage", required_argument, 0, 'd'},
        {"runtime-dir", required_argument, 0, 'r'}, {"no-fsync", no_argument, 0, 'F'},
        {"verbose", no_argument, 0, 'v'}, {"check-config", no_argument, 0, 't'},
        {"help", no_argument, 0, 'h'}, {"version", no_argument, 0, 'V'}, {"allow-root", no_argument, 0, 'R'},
        {"udev-rules", no_argument, 0, 'U'}, {0, 0, 0, 0},
    };
    scicapd_options o = {.fsync = -1};
    int verbose = 0, check = 0, no_config = 0, allow_root = 0, udev = 0, c;
    while ((c = getopt_long(argc, argv, "c:s:d:r:vth", opts, NULL)) != -1) {
        switch (c) {
        case 'c': o.config_path = optarg; break;
        case 'N': no_config = 1; break;
        case 's': o.socket_path = optarg; break;
        case 'd': o.storage_root = optarg; break;
        case 'r': o.runtime_dir = optarg; break;
        case 'F': o.fsync = 0; break;
        case 'R': allow_root = 1; break;
        case 'v': verbose = 1; break;
        case 't': check = 1; break;
        case 'U': udev = 1; break;
        case 'h': usage(stdout); return 0;
        case 'V': printf("scicapd %s\n", SCICAP_VERSION); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "scicapd: unexpected argument '%s'\n", argv[optind]);
        usage(stderr);
        return 2;
    }
    if (!o.config_path && !no_config && access(SCICAPD_CONFIG_DEFAULT_PATH, F_OK) == 0)
        o.config_path = SCICAPD_CONFIG_DEFAULT_PATH;
    /* journald reads "<N>" priority prefixes when stderr is the journal stream */
    sci_log log = {.fd = 2, .level = verbose ? SCI_LOG_DEBUG : SCI_LOG_INFO, .journal = getenv("JOURNAL_STREAM") != NULL,
                   .tag = "scicapd"};
    sci_error err = {0};
    if (check || udev) {
        scicapd_config *cfg;
        if (scicapd_config_load(&cfg, o.config_path, &err) < 0) {
            fprintf(stderr, "scicapd: %s\n", err.msg);
            return 1;
        }
        int rc = 0;
        if (udev && scicapd_udev_rules_write(stdout, cfg, &err) < 0) {
            fprintf(stderr, "scicapd: %s%s%s\n", cfg->path[0] ? cfg->path : "", cfg->path[0] ? ": " : "", err.msg);
            rc = 1;
        } else if (!udev) {
            printf("%s: valid\n", o.config_path ? o.config_path : "built-in defaults");
        }
        scicapd_config_free(cfg);
        return rc;
    }
    const char *inv = getenv("INVOCATION_ID");
    if (geteuid() == 0 && !allow_root && !(inv && inv[0])) {
        sci_log_write(&log, SCI_LOG_ERR, "refusing to run as root outside systemd: the daemon needs no privilege "
                      "(the devices belong to group scicap). Run it as the scicap user (systemctl start scicapd), "
                      "or pass --allow-root if you mean it.");
        return 1;
    }
    scicapd *d;
    if (scicapd_new(&d, &o, &log, &err) < 0) {
        sci_log_write(&log, SCI_LOG_ERR, "cannot start: %s", err.msg);
        return 1;
    }
    scicapd_ready(d);
    int rc = scicapd_run(d);
    scicapd_free(d);
    sci_log_write(&log, SCI_LOG_NOTICE, "stopped");
    return rc < 0 ? 1 : 0;
}

/* scicap — the command line: offline tools and (later) the daemon's client. One file per subcommand. */
#include <stdio.h>
#include <string.h>

#include "base/runtime_env.h"
#include "cli/client.h"
#include "cli/commands.h"
#include "cli/recon_opts.h"
#include "recon/solver.h"

typedef struct command {
    const char *name;
    int (*main)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {
    {"sim", cli_sim_main, "simulate coded snapshots of a scene (video2d, static3d, colour) with its effects"},
    {"recon", cli_recon_main, "reconstruct SCI snapshots with any method below; any .mat, colour"},
    {"batch", cli_batch_main, "many reconstructions: files, folders, globs, captures; resumable; --slurm array jobs"},
    {"status", cli_client_main, "daemon: state, devices, queues"},
    {"devices", cli_client_main, "daemon: the devices it drives and their identities"},
    {"capture", cli_client_main, "daemon: capture snapshots (--recon METHOD, --wait)"},
    {"calibrate", cli_client_main, "daemon: dark frame and measured masks"},
    {"jobs", cli_client_main, "daemon: queued, running and recent jobs (--all: every one)"},
    {"captures", cli_client_main, "daemon: the stored captures and their reconstructions (PSNR, time)"},
    {"cancel", cli_client_main, "daemon: cancel a job"},
    {"watch", cli_client_main, "daemon: follow the event stream with a progress bar"},
    {"reload", cli_client_main, "daemon: reload the configuration"},
    {"shutdown", cli_client_main, "daemon: stop the daemon"},
    {"bench", cli_bench_main, "accuracy against time: every method over its cost knobs on a fixed suite"},
    {"dmd", cli_dmd_main, "TI DLPC900 DMD: list, status, upload masks, start, stop (--emulate: no hardware)"},
};

static void usage(FILE *f)
{
    fprintf(f, "usage: scicap [--version] [--help] COMMAND [ARGS...]\n\n"
               "Video snapshot compressive imaging: simulate, capture and reconstruct.\n\ncommands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(f, "  %-10s %s\n", commands[i].name, commands[i].summary);
    /* the methods as the table lists them (recon/solver.h): a new row shows up here by itself */
    fprintf(f, "\nreconstruction methods (scicap recon --method; the first is the default):\n");
    cli_recon_methods_usage(f, solver_list(NULL), 11);
    fprintf(f, "\n'scicap COMMAND --help' documents each command; man scicap documents them all.\n");
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv);
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    if (strcmp(argv[1], "--version") == 0) {
        const char *core = sci_runtime_env_blas_running();
        const char *asked = getenv("OPENBLAS_CORETYPE"); /* the user's, or base/runtime_env.h's choice */
        printf("scicap %s\nOpenBLAS kernels: %s%s%s%s\n", SCICAP_VERSION, core ? core : "(not linked)",
               asked ? " (OPENBLAS_CORETYPE=" : "", asked ? asked : "", asked ? ")" : "");
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (strcmp(argv[1], commands[i].name) == 0)
            return commands[i].main(argc - 1, argv + 1);
    fprintf(stderr, "scicap: unknown command '%s'\n\n", argv[1]);
    usage(stderr);
    return 2;
}

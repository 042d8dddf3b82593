/* cli/commands.h — the subcommands of `scicap`, one file each (cli/<name>.c); cli/main.c dispatches.
 * Each takes the arguments after the subcommand name (argv[0] is the subcommand) and returns the process exit
 * status: 0 success, 1 runtime failure (message printed to stderr), 2 usage error. */
#ifndef SCICAP_CLI_COMMANDS_H
#define SCICAP_CLI_COMMANDS_H

int cli_recon_main(int argc, char **argv);
int cli_sim_main(int argc, char **argv);
int cli_dmd_main(int argc, char **argv);
int cli_bench_main(int argc, char **argv);
int cli_batch_main(int argc, char **argv);
/* `scicap recon` given several inputs: the same batch as `scicap batch` (cli/batch.c). opts are recon's options
 * (with -o OUTDIR, the batch's folder; the others go to every job's scicap recon), inputs the INPUT arguments. */
int cli_batch_recon(int nopts, char **opts, int ninputs, char **inputs);
/* 1 when one INPUT of scicap recon stands for several: a folder without problem.json, or an unexpanded glob. */
int cli_batch_is_many(const char *input);

#endif

/* cli/client.h — `scicap` as the client of scicapd (docs/protocol.md).
 *
 * cli_client_main: argv[0] is one of status, devices, capture, calibrate, jobs, captures, cancel, watch, reload,
 * shutdown. cli_client_recon: `scicap recon --capture ID [--method M] [--preset P] [--iters N] [--budget S]
 * [--wait]` (cli/recon.c calls it when it sees --capture; ID c000042, c42 or 42). Both take --socket PATH (default
 * $SCICAP_SOCKET, else /run/scicapd/control.sock) and return the exit status: 0 success, 1 failure (the daemon's
 * reason printed, naming the option it concerns; also a cancel of a job that had already finished), 2 usage.
 */
#ifndef SCICAP_CLI_CLIENT_H
#define SCICAP_CLI_CLIENT_H

#include <stdio.h>

#define CLI_CLIENT_DEFAULT_SOCKET "/run/scicapd/control.sock"

int cli_client_main(int argc, char **argv);
int cli_client_recon(int argc, char **argv);
/* Print the help of a daemon command ("status", ..., "reconstruct" for scicap recon --capture). */
void cli_client_usage(FILE *f, const char *name);

#endif

/* cli/recon_opts.h — `scicap recon`'s method settings on the command line, taken from the method table
 * (recon/solver.h): every key of every method is an option --KEY (with '_' as '-'), its type, range, names and
 * help are the table's, and the help text lists the methods and their settings from it. Nothing here restates a
 * method, a preset or a range, so a new row in the table brings its options and help without another edit.
 *
 *     struct option *all = cli_recon_opts_longopts(methods, own);   // own options, then one per setting key
 *     cli_recon_given g = {.methods = methods};
 *     while ((c = getopt_long(argc, argv, shorts, all, &idx)) != -1)
 *         ... default: rc = cli_recon_opts_take(&g, all, c, idx, optarg);   // 1: not a settings option
 *     void *s = solver_settings_new(m);
 *     rc = cli_recon_opts_apply(&g, m, s);                          // preset, options, --set, checks
 *     free(all);
 *
 * Every function takes the table as a parameter (scicap passes solver_list(); a test passes a table with an extra
 * method). Errors are printed to stderr as "scicap recon: ..." and returned as 2 (a usage error, the exit status
 * of cli/commands.h); nothing exits. Not thread-safe only in that getopt is not.
 */
#ifndef SCICAP_CLI_RECON_OPTS_H
#define SCICAP_CLI_RECON_OPTS_H

#include <getopt.h>
#include <stdio.h>

#include "recon/solver.h"

/* getopt `val`s this module handles; a command's own options use other values (letters, or 256 up to 0xfff). */
enum {
    CLI_RECON_OPT_SETTING = 0x1000, /* --KEY VALUE: a method setting (name = the key, or an alias in the .c) */
    CLI_RECON_OPT_SET = 0x2000,     /* --set KEY=VALUE */
    CLI_RECON_OPT_PRESET,           /* --preset fast|balanced|best */
};
/* Is v (a getopt `val`) a settings option's? cli_recon_opts_longopts gives every settings option without a short
 * letter a val of its own (CLI_RECON_OPT_SETTING with a number above bit 16), so that getopt_long calls an
 * abbreviation that fits several options ambiguous and lists them ("--pose-l": --pose-lr, --pose-lr-final) instead
 * of silently taking the first; the abbreviations users rely on are kept as options of their own (--pose for
 * --pose-mode, in the .c). */
#define CLI_RECON_OPT_IS_SETTING(v) (((v) & 0xff00) == CLI_RECON_OPT_SETTING)
/* The val of a setting that also has the short option -c (c a letter of the command's getopt string): getopt_long
 * returns it for the long option and c for the short one; both are settings options here. A command's own option
 * of a key's name (val without CLI_RECON_OPT_SETTING, e.g. recon's -j, --threads) is not: --set reaches that key. */
#define CLI_RECON_OPT_SETTING_SHORT(c) (CLI_RECON_OPT_SETTING | (c))

#define CLI_RECON_GIVEN_MAX 64 /* settings options on one command line */
#define CLI_RECON_SETS_MAX 32  /* --set options on one command line */

/* One settings option as given: the key it sets, the option as spelled (for messages), its text (borrowed from
 * argv). */
typedef struct cli_recon_arg {
    const char *key;
    char option[64];
    const char *text;
} cli_recon_arg;

/* The settings options of one command line, in the order given; zero-initialise and set methods. Borrows the
 * table and argv's strings for its lifetime; holds nothing to free. */
typedef struct cli_recon_given {
    const solver_ops *const *methods; /* NULL-terminated table (borrowed) */
    const char *preset;               /* --preset, or NULL: the method's defaults */
    cli_recon_arg arg[CLI_RECON_GIVEN_MAX];
    int n;
    const char *set[CLI_RECON_SETS_MAX]; /* --set KEY=VALUE, applied after every --KEY option */
    int n_set;
} cli_recon_given;

/* The getopt table: `own` (the command's options, {0}-terminated; a name there wins over a setting of the same
 * name, which --set still reaches), then --KEY for every other key of every method in the table (aliases left
 * out), then the kept spellings (--plain, --distortion, --pose) the command does not list itself. Settings options
 * given val CLI_RECON_OPT_SETTING get one of their own (CLI_RECON_OPT_IS_SETTING above). One malloc'd block
 * holding the names too: free() it. NULL on ENOMEM. */
struct option *cli_recon_opts_longopts(const solver_ops *const *methods, const struct option *own);

/* The option getopt_long returned (c, and idx = its longindex, -1 for a short option) if it is a settings option:
 * recorded in g. Returns 0, 1 when c is not a settings option (nothing recorded), or 2 after a message (--set
 * without '=', too many options). The text is checked when applied, once the method is known. */
int cli_recon_opts_take(cli_recon_given *g, const struct option *all, int c, int idx, const char *arg);

/* Apply g to settings (m's defaults, freshly made): the preset, then the ACTION options (a ladder step sets several
 * keys, which the options given with it then override), then the others in the order given, then every --set,
 * then solver_settings_check. Each text is read by its field's type and checked against its range; an option m
 * has no key for is ignored (the common options map onto whichever method runs) unless it is an ACTION, which is
 * refused naming the methods that have it. 0, or 2 after a message. */
int cli_recon_opts_apply(const cli_recon_given *g, const solver_ops *m, void *settings);

/* The methods, one a line: "  NAME  summary" with the name in a column of `width`. */
void cli_recon_methods_usage(FILE *f, const solver_ops *const *methods, int width);

/* The presets ("fast, balanced or best") and each method's settings as options, with their short letters and
 * aliases from `all` (cli_recon_opts_longopts's table), value, help and range; a group of keys several methods
 * share is listed once under all their names. */
void cli_recon_opts_usage(FILE *f, const solver_ops *const *methods, const struct option *all);

#endif

/* The documentation states what is, not how it was found: README.md, the Markdown files in docs/ and the man pages in docs/man/ name
 * no session, issue or round of the project's history. That history is in git log.
 *
 * What counts as history (case-insensitive, across line breaks):
 *     session 17, sessions 11–16, session-4 defaults; the previous / last / next / this / same ... session
 *     issue 15, issue #15, issues 6 and 15, issue-15 recipe; the (its targets, its minutes); must-show
 *     the eighth round, the 18th / 18-th round, this / previous / next ... round, round 3, rounds 1–4, the rounds
 *     the session could / did / began ...; an issue's target
 * What does not: round as in rounding (round(x), rounded, rounds to nearest, round-trip, round robin, around), a
 * Python or login session, an issue that is not numbered.
 *
 * The text is read as words (runs of letters and digits; roff escapes such as \fB and \- skipped), each with the
 * line it starts on, so a phrase wrapped over two lines is still found; a failure names file:line and the phrase.
 * `test_docs_history FILE...` scans the given files instead and prints the hits (exit 1 if any). */
#include <ctype.h>
#include <glob.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

typedef struct word {
    char s[32];   /* lower case, truncated */
    int line;     /* where it starts */
    char after;   /* the character right after it ('\0' at the end of the text) */
    char after2;  /* and the one after that */
    char before;  /* the character right before it ('\0' at the start) */
} word;

typedef struct words {
    word *w;
    int n, cap;
} words;

static void words_add(words *ws, const char *text, const char *p, size_t len, int line, const char *end)
{
    if (ws->n == ws->cap) {
        ws->cap = ws->cap ? 2 * ws->cap : 1024;
        ws->w = realloc(ws->w, (size_t)ws->cap * sizeof *ws->w);
        assert_non_null(ws->w);
    }
    word *w = &ws->w[ws->n++];
    size_t k = len < sizeof w->s - 1 ? len : sizeof w->s - 1;
    for (size_t i = 0; i < k; i++)
        w->s[i] = (char)tolower((unsigned char)p[i]);
    w->s[k] = '\0';
    w->line = line;
    w->after = p + len < end ? p[len] : '\0';
    w->after2 = p + len + 1 < end ? p[len + 1] : '\0';
    w->before = p > text ? p[-1] : '\0';
}

/* Split text into words; `roff`: skip the escapes \fX, \f(XX, \(XX and \X. */
static void words_split(const char *text, size_t size, int roff, words *ws)
{
    const char *p = text, *end = text + size;
    int line = 1;
    while (p < end) {
        if (*p == '\n') {
            line++, p++;
        } else if (roff && *p == '\\' && p + 1 < end) {
            if (p[1] == 'f' && p + 2 < end)
                p += p[2] == '(' ? 5 : 3;
            else if (p[1] == '(')
                p += 4;
            else
                p += 2;
        } else if (isalnum((unsigned char)*p)) {
            const char *q = p;
            while (q < end && isalnum((unsigned char)*q))
                q++;
            words_add(ws, text, p, (size_t)(q - p), line, end);
            p = q;
        } else {
            p++;
        }
    }
}

static int is_number(const char *s)
{
    if (!*s)
        return 0;
    for (; *s; s++)
        if (!isdigit((unsigned char)*s))
            return 0;
    return 1;
}

static int in(const char *s, const char *const *list)
{
    for (; *list; list++)
        if (strcmp(s, *list) == 0)
            return 1;
    return 0;
}

static const char *const ORDINALS[] = {"first",      "second",      "third",      "fourth",     "fifth",
                                       "sixth",      "seventh",     "eighth",     "ninth",      "tenth",
                                       "eleventh",   "twelfth",     "thirteenth", "fourteenth", "fifteenth",
                                       "sixteenth",  "seventeenth", "eighteenth", "nineteenth", "twentieth",
                                       "thirtieth",  NULL};
/* the words before "session" or "round" that make it a point in the project's history */
static const char *const WHICH[] = {"this", "that", "previous", "last", "next", "earlier", "later", "former", "same",
                                    "current", NULL};

/* 13th, 2nd: a number with an ordinal suffix */
static int numeric_ordinal(const char *s)
{
    size_t n = strlen(s);
    if (n < 3 || !isdigit((unsigned char)s[0]))
        return 0;
    const char *suf = s + n - 2;
    for (size_t i = 0; i < n - 2; i++)
        if (!isdigit((unsigned char)s[i]))
            return 0;
    return strcmp(suf, "st") == 0 || strcmp(suf, "nd") == 0 || strcmp(suf, "rd") == 0 || strcmp(suf, "th") == 0;
}

/* Is word i an ordinal: "eighth", "13th", or "13-th" / "13 th" (a number then a suffix word)? */
static int ordinal_at(const words *ws, int i)
{
    if (i < 0)
        return 0;
    const char *s = ws->w[i].s;
    if (in(s, ORDINALS) || numeric_ordinal(s))
        return 1;
    static const char *const SUF[] = {"st", "nd", "rd", "th", NULL};
    return in(s, SUF) && i > 0 && is_number(ws->w[i - 1].s);
}

/* A whole number after word i (not the start of a decimal such as 0.5, nor an argument or a man section in
 * parentheses: round(3)). */
static int integer_follows(const words *ws, int i)
{
    if (i + 1 >= ws->n || !is_number(ws->w[i + 1].s))
        return 0;
    const word *nw = &ws->w[i + 1];
    return nw->before != '(' && !(nw->after == '.' && isdigit((unsigned char)nw->after2));
}

/* If a history phrase starts at or around word i, its description; else NULL. */
static const char *history_at(const words *ws, int i)
{
    const char *s = ws->w[i].s, *prev = i > 0 ? ws->w[i - 1].s : "", *next = i + 1 < ws->n ? ws->w[i + 1].s : "";
    if (strcmp(s, "session") == 0 || strcmp(s, "sessions") == 0) {
        if (integer_follows(ws, i))
            return "a numbered session";
        if (in(prev, WHICH) || ordinal_at(ws, i - 1))
            return "a session of the project's history";
        static const char *const DID[] = {"began", "ended", "could", "did", "found", "measured", "ran", NULL};
        if (strcmp(prev, "the") == 0 && in(next, DID))
            return "the session (of the project's history)";
        return NULL;
    }
    if (strcmp(s, "issue") == 0 || strcmp(s, "issues") == 0) {
        if (integer_follows(ws, i))
            return "a numbered issue";
        if (strcmp(s, "issue") == 0 && strcmp(next, "s") == 0 && ws->w[i].after == '\'')
            return "the issue's (a tracker issue's requirement)";
        static const char *const TARGET[] = {"target", "targets", "requirement", "requirements", NULL};
        if (strcmp(s, "issue") == 0 && in(next, TARGET))
            return "an issue's target (a tracker issue's requirement)";
        return NULL;
    }
    if (strcmp(s, "must") == 0 && strcmp(next, "show") == 0 && ws->w[i].after == '-')
        return "the issue's must-show";
    if (strcmp(s, "round") == 0 || strcmp(s, "rounds") == 0) {
        static const char *const NOT[] = {"trip", "trips", "tripped", "robin", NULL};
        if (in(next, NOT))
            return NULL;
        if (ordinal_at(ws, i - 1))
            return "an ordinal round";
        if (in(prev, WHICH))
            return "a round of the project's history";
        if (integer_follows(ws, i))
            return "a numbered round";
        if (strcmp(s, "rounds") == 0 && (strcmp(prev, "the") == 0 || strcmp(prev, "these") == 0 ||
                                         strcmp(prev, "those") == 0 || strcmp(prev, "both") == 0))
            return "the rounds";
        return NULL;
    }
    return NULL;
}

/* The hits of text as "file:line: phrase (why)" lines appended to out; returns their count. */
static int scan_text(const char *name, const char *text, size_t size, int roff, FILE *out)
{
    words ws = {0};
    words_split(text, size, roff, &ws);
    int hits = 0;
    for (int i = 0; i < ws.n; i++) {
        const char *why = history_at(&ws, i);
        if (!why)
            continue;
        int a = i > 0 ? i - 1 : i, b = i + 1 < ws.n ? i + 1 : i;
        fprintf(out, "%s:%d: '%s %s %s': %s\n", name, ws.w[i].line, ws.w[a].s, ws.w[i].s, b != i ? ws.w[b].s : "",
                why);
        hits++;
    }
    free(ws.w);
    return hits;
}

static char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t n = 0, cap = 0;
    for (;;) {
        if (n + 4096 > cap) {
            cap = cap ? 2 * cap : 65536;
            buf = realloc(buf, cap + 1);
            if (!buf)
                break;
        }
        size_t r = fread(buf + n, 1, cap - n, f);
        n += r;
        if (r == 0)
            break;
    }
    fclose(f);
    if (buf)
        buf[n] = '\0';
    *size = n;
    return buf;
}

static int is_roff(const char *path)
{
    return strncmp(path, "docs/man/", 9) == 0 || strstr(path, "/man/") != NULL;
}

static int scan_file(const char *path, FILE *out)
{
    size_t size = 0;
    char *text = slurp(path, &size);
    if (!text)
        fail_msg("%s: cannot read it (run from the top of the source tree)", path);
    int hits = scan_text(path, text, size, is_roff(path), out);
    free(text);
    return hits;
}

/* Scan every file matching pattern; fail naming each hit. */
static void scan_glob(const char *pattern, int at_least)
{
    glob_t g;
    int rc = glob(pattern, 0, NULL, &g);
    if (rc == GLOB_NOMATCH)
        fail_msg("%s: no file (run from the top of the source tree)", pattern);
    assert_int_equal(rc, 0);
    assert_true((int)g.gl_pathc >= at_least);
    char *report = NULL;
    size_t report_size = 0;
    FILE *out = open_memstream(&report, &report_size);
    assert_non_null(out);
    int hits = 0;
    for (size_t i = 0; i < g.gl_pathc; i++)
        hits += scan_file(g.gl_pathv[i], out);
    fclose(out);
    printf("%s: %zu files, %d history phrases\n", pattern, g.gl_pathc, hits);
    if (hits) {
        fputs(report, stdout);
        fflush(stdout);
    }
    free(report);
    globfree(&g);
    if (hits)
        fail_msg("%s: %d phrases of project history (file:line above); state what is, the history is in git log",
                 pattern, hits);
}

static int hits_in(const char *text, int roff)
{
    FILE *out = fopen("/dev/null", "w");
    assert_non_null(out);
    int n = scan_text("example", text, strlen(text), roff, out);
    fclose(out);
    return n;
}

/* Each of n phrases (roff when it holds a font escape) must give `want` hits; `why` names a failure. */
static void expect_hits(const char *const *phrases, size_t n, int want, const char *why)
{
    for (size_t i = 0; i < n; i++)
        if (hits_in(phrases[i], strstr(phrases[i], "\\f") != NULL) != want)
            fail_msg("%s: \"%s\"", why, phrases[i]);
}

/* The scanner on phrases the project's documents used to hold, and on legitimate uses of the same words. */
static void test_scanner_examples(void **state)
{
    (void)state;
    static const char *const history[] = {
        "measured in session 17 on the corridor",
        "Sessions 11–16 ran RayFormer 1250 steps",
        "the session-4 defaults",
        "(session\n7 defaults)",
        "as the previous session found",
        "the recipe of issue 15",
        "With the issue-15 recipe",
        "see issue #42",
        "Issues 6 and 15",
        "over the issue's 5 minutes",
        "the must-show's three of four",
        "The eighteenth round measured it",
        "the\nseventeenth round",
        "the 18th round",
        "the 8-th round",
        "Second round, the corridor",
        "what this round changed",
        "as in the previous round",
        "round 3 of the study",
        "rounds 1–4 labelled",
        "The rounds at a glance",
        "at 32 samples (issue target < 0.6 s)",
        "the comparison the session could not hold",
        ".SH NOTES\nmeasured in \\fBsession 9\\fR",
        "the \\fIthird round\\fP",
    };
    expect_hits(history, sizeof history / sizeof history[0], 1, "not found once");
    static const char *const legitimate[] = {
        "counts = clamp(round(electrons / gain), 0, 255)",
        "rounded to an integer",
        "a float backward carries ~1e-7 per-operation rounding",
        "Float stacks round-trip bit for bit",
        "the round trip takes 3 ms",
        "kernel lines around it",
        "values round to nearest even",
        "x rounds to 0.5 steps",
        "round 0.5 up",
        "round-robin over the workers",
        "in one Python session",
        "a D-Bus session bus",
        "the issue with the old reader",
        "one round of denoising per iteration",
        "each round of the ADMM loop",
        "a session-less client",
        "\\fBround\\fR(3) in libm",
        "issued 15 requests",
        "the sessions file",
    };
    expect_hits(legitimate, sizeof legitimate / sizeof legitimate[0], 0, "a legitimate phrase taken for history");
}

static void test_readme(void **state)
{
    (void)state;
    scan_glob("README.md", 1);
}

static void test_docs_markdown(void **state)
{
    (void)state;
    scan_glob("docs/*.md", 5);
}

static void test_man_pages(void **state)
{
    (void)state;
    scan_glob("docs/man/*", 2);
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
            fprintf(stderr, "usage: test_docs_history [FILE...]   (no FILE: the cmocka tests on README.md, docs/)\n");
            return 2;
        }
        int hits = 0;
        for (int i = 1; i < argc; i++) {
            size_t size = 0;
            char *text = slurp(argv[i], &size);
            if (!text) {
                fprintf(stderr, "test_docs_history: %s: cannot read it\n", argv[i]);
                return 2;
            }
            hits += scan_text(argv[i], text, size, is_roff(argv[i]), stdout);
            free(text);
        }
        return hits ? 1 : 0;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scanner_examples),
        cmocka_unit_test(test_readme),
        cmocka_unit_test(test_docs_markdown),
        cmocka_unit_test(test_man_pages),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

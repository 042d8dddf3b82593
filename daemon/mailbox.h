/* daemon/mailbox.h — messages from the worker threads to the event loop, which alone writes to sockets.
 *
 * A thread posts a finished protocol line (reply or event); the loop is woken through an eventfd, takes every
 * letter at once (the lock is held only to unlink the list) and writes them to the clients. Order is kept per
 * poster. Thread-safe.
 */
#ifndef SCICAP_DAEMON_MAILBOX_H
#define SCICAP_DAEMON_MAILBOX_H

#include <stdint.h>

typedef struct scicapd_letter {
    struct scicapd_letter *next;
    uint64_t client;  /* connection to send to (0: none) */
    long owner;       /* uid whose job it concerns (watchers see it if theirs or admin); -1: everyone's */
    int broadcast;    /* 1: also to every watching connection allowed to see it */
    char *line;       /* newline-terminated JSON, owned */
} scicapd_letter;

typedef struct scicapd_mailbox scicapd_mailbox;

int scicapd_mailbox_new(scicapd_mailbox **out);
void scicapd_mailbox_free(scicapd_mailbox *mb); /* frees letters not taken */
/* The eventfd to poll for POLLIN. */
int scicapd_mailbox_fd(const scicapd_mailbox *mb);
/* Post `line` (stolen; NULL is ignored, e.g. after an allocation failure) for connection `client`; with
 * broadcast, also for the watchers that may see events of uid `owner` (SCICAPD_OWNER_ALL: every watcher). */
void scicapd_mailbox_post(scicapd_mailbox *mb, uint64_t client, long owner, int broadcast, char *line);
/* owner of a letter every watcher may see (device events, not about one user's job) */
#define SCICAPD_OWNER_ALL (-1L)
/* Every letter posted so far, oldest first (caller frees with scicapd_letters_free); clears the eventfd. */
scicapd_letter *scicapd_mailbox_take(scicapd_mailbox *mb);
void scicapd_letters_free(scicapd_letter *l);

#endif

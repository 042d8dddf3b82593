/* daemon/mailbox.c — a locked singly linked list plus an eventfd. */
#include "daemon/mailbox.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <sys/eventfd.h>
#include <unistd.h>

struct scicapd_mailbox {
    pthread_mutex_t mu;
    scicapd_letter *head, **tail;
    int fd;
};

int scicapd_mailbox_new(scicapd_mailbox **out)
{
    scicapd_mailbox *mb = calloc(1, sizeof *mb);
    if (!mb)
        return -ENOMEM;
    mb->fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (mb->fd < 0) {
        int rc = -errno;
        free(mb);
        return rc;
    }
    pthread_mutex_init(&mb->mu, NULL);
    mb->tail = &mb->head;
    *out = mb;
    return 0;
}

void scicapd_letters_free(scicapd_letter *l)
{
    while (l) {
        scicapd_letter *n = l->next;
        free(l->line);
        free(l);
        l = n;
    }
}

void scicapd_mailbox_free(scicapd_mailbox *mb)
{
    if (!mb)
        return;
    scicapd_letters_free(mb->head);
    close(mb->fd);
    pthread_mutex_destroy(&mb->mu);
    free(mb);
}

int scicapd_mailbox_fd(const scicapd_mailbox *mb) { return mb->fd; }

void scicapd_mailbox_post(scicapd_mailbox *mb, uint64_t client, long owner, int broadcast, char *line)
{
    if (!line)
        return;
    scicapd_letter *l = malloc(sizeof *l);
    if (!l) {
        free(line);
        return;
    }
    *l = (scicapd_letter){.client = client, .owner = owner, .broadcast = broadcast, .line = line};
    pthread_mutex_lock(&mb->mu);
    *mb->tail = l;
    mb->tail = &l->next;
    pthread_mutex_unlock(&mb->mu);
    uint64_t one = 1;
    ssize_t w = write(mb->fd, &one, sizeof one); /* EAGAIN only when the counter is huge: already readable */
    (void)w;
}

scicapd_letter *scicapd_mailbox_take(scicapd_mailbox *mb)
{
    uint64_t v;
    ssize_t r = read(mb->fd, &v, sizeof v);
    (void)r;
    pthread_mutex_lock(&mb->mu);
    scicapd_letter *l = mb->head;
    mb->head = NULL;
    mb->tail = &mb->head;
    pthread_mutex_unlock(&mb->mu);
    return l;
}

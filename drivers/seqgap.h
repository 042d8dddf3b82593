/* drivers/seqgap.h — frames lost, counted from gaps in the driver's 32-bit frame sequence numbers.
 *
 * V4L2 counts every frame the driver saw, delivered or not (buffer.rst): a frame that arrives with sequence s
 * after one with sequence p means s - p - 1 frames were lost, in uint32 arithmetic so that the wrap from
 * 0xFFFFFFFF to 0 is not a loss. A step of 0 is a repeated number (counted, not a loss); a step of 2^31 or more is
 * taken as the counter going backwards (the stream restarted), counted as a reset, not as four billion losses —
 * so a real forward gap of 2^31 frames or more cannot be told apart, which no capture reaches.
 *
 * Plain data, no allocation; one tracker per stream; not thread-safe per object.
 *
 *     seqgap g; seqgap_reset(&g);
 *     uint32_t lost = seqgap_push(&g, buf.sequence);  // 0 for the first frame
 */
#ifndef SCICAP_DRIVERS_SEQGAP_H
#define SCICAP_DRIVERS_SEQGAP_H

#include <stdint.h>

typedef struct seqgap {
    int primed;       /* 0 until the first sequence number was seen */
    uint32_t last;    /* the last sequence number seen */
    uint64_t frames;  /* frames pushed */
    uint64_t lost;    /* frames lost in forward gaps, total */
    uint64_t gaps;    /* number of forward gaps (events, not frames) */
    uint64_t repeats; /* steps of 0 */
    uint64_t resets;  /* steps backwards (>= 2^31 forward) */
} seqgap;

/* Forget everything: call at every stream start (the driver restarts its count at STREAMON). */
void seqgap_reset(seqgap *g);
/* Record frame `seq`; returns the number of frames lost immediately before it (0 for the first, a repeat or
 * a reset). */
uint32_t seqgap_push(seqgap *g, uint32_t seq);
/* Frames lost between two sequence numbers, wrap-safe: b - a - 1 in uint32, 0 if b == a or b is behind a. */
uint32_t seqgap_between(uint32_t a, uint32_t b);

#endif

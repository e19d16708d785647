// The figures of the simulated suit, in simulated time: frame starts (the arbiter's first poll
// of each round, its sampling instant), periods, streams, frames per simulated second, and
// the cycles each board spent awake in every 20 ms frame out of the 320,000 it has.
#include <stdio.h>
#include <string.h>

#include "suit_host.h"

#define MAX_STREAMS 64
#define MAX_SECONDS 3600

typedef struct {
    cycle_t first, last;  // frame starts
    uint64_t frames;
} stream_t;

typedef struct {
    uint64_t n;
    double sum;
    cycle_t min, max;
} figure_t;

static board_t* boards;
static stream_t streams[MAX_STREAMS];
static int n_streams;  // streams[(n_streams - 1) % MAX_STREAMS] is the current one
static cycle_t last_start;
static int have_start;
static cycle_t awake_at_start[N_BOARDS];
static cycle_t last_radio_end;
static figure_t period, busy, awake[N_BOARDS];
static uint64_t late_frames;  // periods longer than 21 ms (the firmware's LATE_US)
static uint16_t per_second[MAX_SECONDS];  // frames in each second of the current stream
static int seconds_done;                  // complete seconds counted in per_second
static uint16_t min_per_second = 0xFFFF, max_per_second;

void stats_init(board_t b[N_BOARDS]) { boards = b; }

static void add(figure_t* f, cycle_t v) {
    if (f->n == 0 || v < f->min) f->min = v;
    if (f->n == 0 || v > f->max) f->max = v;
    f->sum += (double)v;
    ++f->n;
}

// Simulated second k of a stream spans [first + k s - 10 ms, first + (k + 1) s - 10 ms): its
// edges fall half a period away from the frames, so that their few microseconds of jitter
// cannot move a frame from one second to the next.
#define SECOND_OFFSET (CYCLES_PER_FRAME / 2)

static void close_seconds(const stream_t* s) {
    // the seconds before the one of the stream's last frame are complete
    const int upto = (int)((s->last - s->first + SECOND_OFFSET) / F_CPU_HZ);
    while (seconds_done < upto && seconds_done < MAX_SECONDS) {
        const uint16_t c = per_second[seconds_done];
        if (c < min_per_second) min_per_second = c;
        if (c > max_per_second) max_per_second = c;
        ++seconds_done;
    }
}

void stats_frame_start(cycle_t at) {
    const int same_stream = have_start && at - last_start < CYCLES_PER_FRAME * 3 / 2;
    if (same_stream) {
        add(&period, at - last_start);
        if (at - last_start > CYCLES_PER_FRAME + F_CPU_HZ / 1000) ++late_frames;
        for (int i = 0; i < N_BOARDS; ++i) add(&awake[i], boards[i].awake - awake_at_start[i]);
        if (last_radio_end > last_start) add(&busy, last_radio_end - last_start);
        stream_t* s = &streams[(n_streams - 1) % MAX_STREAMS];
        s->last = at;
        ++s->frames;
        close_seconds(s);
    } else {
        stream_t* s = &streams[n_streams % MAX_STREAMS];
        ++n_streams;
        s->first = s->last = at;
        s->frames = 1;
        memset(per_second, 0, sizeof per_second);
        seconds_done = 0;
    }
    const stream_t* s = &streams[(n_streams - 1) % MAX_STREAMS];
    const uint64_t second = (at - s->first + SECOND_OFFSET) / F_CPU_HZ;
    if (second < MAX_SECONDS) ++per_second[second];
    for (int i = 0; i < N_BOARDS; ++i) awake_at_start[i] = boards[i].awake;
    last_start = at;
    have_start = 1;
}

void stats_radio_byte_end(cycle_t at) { last_radio_end = at; }

static int put_figure(char* out, int size, const char* name, const figure_t* f, double scale) {
    if (f->n == 0) return snprintf(out, (size_t)size, "\"%s\": null", name);
    return snprintf(out, (size_t)size, "\"%s\": {\"mean\": %.3f, \"min\": %.3f, \"max\": %.3f, \"n\": %llu}",
                    name, f->sum / (double)f->n * scale, (double)f->min * scale,
                    (double)f->max * scale, (unsigned long long)f->n);
}

#define PUT(...)                                                         \
    do {                                                                 \
        int w_ = snprintf(out + len, (size_t)(size - len), __VA_ARGS__); \
        if (w_ > 0) len = len + w_ < size ? len + w_ : size - 1;         \
    } while (0)
#define PUT_FIGURE(name, f, scale)                                    \
    do {                                                              \
        int w_ = put_figure(out + len, size - len, name, f, scale);   \
        if (w_ > 0) len = len + w_ < size ? len + w_ : size - 1;      \
    } while (0)

void stats_write_json(char* out, int size, cycle_t now, double wall_s, double recent_factor,
                      board_t b[N_BOARDS], int final) {
    int len = 0;
    const double sim_s = (double)now / F_CPU_HZ;
    const wire_counters_t* w = wires_counters();
    PUT("{\"final\": %s, \"sim_s\": %.6f, \"wall_s\": %.3f, \"factor\": %.4f, "
        "\"factor_recent\": %.4f, \"frames\": %llu, \"late_frames\": %llu, ",
        final ? "true" : "false", sim_s, wall_s, wall_s > 0 ? sim_s / wall_s : 0.0, recent_factor,
        (unsigned long long)w->frames, (unsigned long long)late_frames);
    PUT_FIGURE("period_us", &period, 1e6 / F_CPU_HZ);
    PUT(", ");
    PUT_FIGURE("arbiter_busy_us", &busy, 1e6 / F_CPU_HZ);
    PUT(", \"frames_per_second\": ");
    if (max_per_second)
        PUT("{\"min\": %u, \"max\": %u}", min_per_second, max_per_second);
    else
        PUT("null");
    PUT(", \"cycles_per_frame\": {");
    for (int i = 0; i < N_BOARDS; ++i) {
        PUT("%s", i ? ", " : "");
        PUT_FIGURE(b[i].name, &awake[i], 1.0);
    }
    PUT("}, \"streams\": [");
    const int first = n_streams > MAX_STREAMS ? n_streams - MAX_STREAMS : 0;
    for (int i = first; i < n_streams; ++i) {
        const stream_t* s = &streams[i % MAX_STREAMS];
        PUT("%s{\"start_s\": %.6f, \"last_s\": %.6f, \"frames\": %llu}", i > first ? ", " : "",
            (double)s->first / F_CPU_HZ, (double)s->last / F_CPU_HZ,
            (unsigned long long)s->frames);
    }
    PUT("], \"counters\": {\"misrouted\": %llu, \"cut\": %llu, \"unheard\": %llu, "
        "\"host_bytes_in\": %llu, \"host_bytes_lost\": %llu, \"host_bytes_held\": %llu, "
        "\"radio_bytes_out\": %llu, \"framing_errors\": %llu, \"overruns\": [",
        (unsigned long long)w->misrouted, (unsigned long long)w->cut,
        (unsigned long long)w->unheard, (unsigned long long)w->host_bytes_in,
        (unsigned long long)w->host_bytes_lost, (unsigned long long)w->host_bytes_held,
        (unsigned long long)w->radio_bytes_out, (unsigned long long)w->framing_errors);
    for (int i = 0; i < N_BOARDS; ++i)
        PUT("%s%llu", i ? ", " : "", (unsigned long long)b[i].overruns);
    PUT("], \"polls\": [");
    for (int k = 0; k < N_CLUSTERS; ++k)
        PUT("%s%llu", k ? ", " : "", (unsigned long long)w->polls[k]);
    PUT("], \"i2c_bytes\": [");
    for (int k = 0; k < N_CLUSTERS; ++k)
        PUT("%s%llu", k ? ", " : "", (unsigned long long)chips_i2c_bytes(k));
    PUT("], \"i2c_nacks\": [");
    for (int k = 0; k < N_CLUSTERS; ++k)
        PUT("%s%llu", k ? ", " : "", (unsigned long long)chips_nacks(k));
    PUT("], \"twi_stalls\": [");
    for (int k = 0; k < N_CLUSTERS; ++k)
        PUT("%s%llu", k ? ", " : "", (unsigned long long)b[1 + k].twi_stalls);
    PUT("], \"lost_events\": [");
    for (int i = 0; i < N_BOARDS; ++i)
        PUT("%s%llu", i ? ", " : "", (unsigned long long)b[i].dropped_events);
    PUT("]}, \"boards\": {");
    for (int i = 0; i < N_BOARDS; ++i)
        PUT("%s\"%s\": \"%s\"", i ? ", " : "", b[i].name, board_state_name(&b[i]));
    PUT("}, \"pc\": {");  // byte addresses, as avr-objdump shows them
    for (int i = 0; i < N_BOARDS; ++i)
        PUT("%s\"%s\": \"0x%04x\"", i ? ", " : "", b[i].name, (unsigned)b[i].avr->pc);
    PUT("}}");
}

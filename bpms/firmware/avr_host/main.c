// avr_suit ARBITER.hex CLUSTER.hex: the simulated suit's boards, driven over stdin/stdout by
// bpms/firmware/avr_suit.py. The byte protocol is described in bridge.h.
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <simavr/avr_adc.h>

#include "bridge.h"
#include "suit_host.h"

// Real time: a lag of up to this much is made up by running faster (a hiccup of the host);
// beyond it the simulated clock simply falls behind.
#define MAX_CATCH_UP_S 0.05

static board_t boards[N_BOARDS];
static const char* board_names[N_BOARDS] = {"arbiter",  "cluster0", "cluster1", "cluster2",
                                            "cluster3", "cluster4", "cluster5"};
static motion_table_t table;
static bridge_config_t config;
static bridge_sensor_off_t* schedule;
static bridge_bus_stuck_t* stuck;
static uint8_t switched_off[18][3];  // runtime switches from the host side ('O')

static double wall_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static int read_exact(void* buf, size_t n) {
    uint8_t* p = buf;
    while (n) {
        ssize_t r = read(0, p, n);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return -1;
        p += r;
        n -= (size_t)r;
    }
    return 0;
}

static void write_all(const void* buf, size_t n) {
    const uint8_t* p = buf;
    while (n) {
        ssize_t w = write(1, p, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) exit(0);  // the host side went away
        p += w;
        n -= (size_t)w;
    }
}

static void send_message(uint8_t type, const uint8_t* data, size_t n) {
    while (n > 0 || type == MSG_STATUS) {
        const size_t chunk = n > 65535 ? 65535 : n;
        uint8_t head[3] = {type, (uint8_t)(chunk & 0xFF), (uint8_t)(chunk >> 8)};
        write_all(head, 3);
        write_all(data, chunk);
        data += chunk;
        n -= chunk;
        if (type == MSG_STATUS) break;
    }
}

static void send_status(cycle_t now, double wall_s, double recent, int final) {
    static char json[16384];
    stats_write_json(json, sizeof json, now, wall_s, recent, boards, final);
    send_message(MSG_STATUS, (const uint8_t*)json, strlen(json));
}

static int read_config(void) {
    char magic[8];
    if (read_exact(magic, 8) || memcmp(magic, BRIDGE_MAGIC, 8) != 0) {
        fprintf(stderr, "avr_suit: stdin does not start with the bridge header\n");
        return -1;
    }
    if (read_exact(&config, sizeof config)) return -1;
    if (config.n_sensor_off) {
        schedule = calloc(config.n_sensor_off, sizeof *schedule);
        if (!schedule || read_exact(schedule, config.n_sensor_off * sizeof *schedule)) return -1;
    }
    if (config.n_bus_stuck) {
        stuck = calloc(config.n_bus_stuck, sizeof *stuck);
        if (!stuck || read_exact(stuck, config.n_bus_stuck * sizeof *stuck)) return -1;
    }
    const size_t n = (size_t)config.n_samples * BRIDGE_VALUES_PER_SAMPLE;
    int16_t* values = malloc(n * sizeof *values + 1);
    if (!values || read_exact(values, n * sizeof *values)) return -1;
    table.n_samples = config.n_samples;
    table.values = values;
    return 0;
}

// Host messages arrive in pieces: keep what is not a whole message yet.
static uint8_t inbuf[1 << 16];
static size_t inlen;
static int quit;

static void handle_input(cycle_t now) {
    for (;;) {
        ssize_t r = read(0, inbuf + inlen, sizeof inbuf - inlen);
        if (r > 0) {
            inlen += (size_t)r;
            continue;
        }
        if (r == 0) quit = 1;  // end of input: the host side closed
        break;
    }
    size_t at = 0;
    while (at < inlen) {
        const uint8_t type = inbuf[at];
        if (type == MSG_QUIT) {
            quit = 1;
            at += 1;
        } else if (type == MSG_HOST_BYTES) {
            if (inlen - at < 3) break;
            const size_t n = inbuf[at + 1] | ((size_t)inbuf[at + 2] << 8);
            if (inlen - at < 3 + n) break;
            wires_host_bytes(inbuf + at + 3, (int)n);
            at += 3 + n;
        } else if (type == MSG_SWITCH) {
            if (inlen - at < 4) break;
            const uint8_t imu = inbuf[at + 1], sensor = inbuf[at + 2], on = inbuf[at + 3];
            if (imu < 18 && sensor < 3) switched_off[imu][sensor] = !on;
            at += 4;
        } else {
            fprintf(stderr, "avr_suit: unknown message 0x%02x from the host side at %.3f s\n",
                    type, (double)now / F_CPU_HZ);
            quit = 1;
            return;
        }
    }
    memmove(inbuf, inbuf + at, inlen - at);
    inlen -= at;
}

static void apply_parts(cycle_t now) {
    const uint64_t ms = now / (F_CPU_HZ / 1000);
    for (int imu = 0; imu < 18; ++imu)
        for (int s = 0; s < 3; ++s) {
            int on = !switched_off[imu][s];
            for (uint32_t i = 0; i < config.n_sensor_off; ++i) {
                const bridge_sensor_off_t* e = &schedule[i];
                if (e->imu == imu && e->sensor == s && ms >= e->from_ms && ms < e->to_ms) on = 0;
            }
            if (on != chips_powered(imu, s)) chips_power(imu, s, on);
        }
    for (int k = 0; k < N_CLUSTERS; ++k) {
        int held = 0;
        for (uint32_t i = 0; i < config.n_bus_stuck; ++i)
            if (stuck[i].cluster == k && ms >= stuck[i].from_ms && ms < stuck[i].to_ms) held = 1;
        boards[1 + k].bus_stuck = held;
    }
    // battery: cell -> 100k -> A0 -> 100k -> GND (docs/firmware.md, "Battery divider"). The
    // ATmega328P's ADC reads floor(Vin * 1024 / Vref); simavr's scales by 1023, so it gets the
    // lowest millivolt value that makes it read the data sheet's count.
    static uint32_t last_pin_mv;
    double cell = config.battery_mv - (double)config.drain_uv_per_h * 1e-3 * ((double)now / F_CPU_HZ) / 3600.0;
    if (cell < 2600.0) cell = 2600.0;
    uint32_t counts = (uint32_t)(cell * 100.0 / 200.0 * 1024.0 / 3300.0);
    if (counts > 1023) counts = 1023;
    const uint32_t pin_mv = (counts * 3300u + 1022u) / 1023u;
    if (pin_mv != last_pin_mv) {
        avr_raise_irq(avr_io_getirq(boards[ARBITER].avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0), pin_mv);
        last_pin_mv = pin_mv;
    }
    for (int i = 0; i < N_BOARDS; ++i) board_sync_baud(&boards[i]);
}

static void flush_radio(void) {
    static uint8_t buf[65536];
    int n;
    while ((n = wires_take_radio(buf, sizeof buf)) > 0) send_message(MSG_RADIO_BYTES, buf, (size_t)n);
}

// Wait until the wall clock reaches `until` (s) or the host side sends something.
static void wait_for(double until) {
    double left = until - wall_now();
    if (left <= 0) return;
    struct pollfd fd = {.fd = 0, .events = POLLIN};
    struct timespec ts = {.tv_sec = (time_t)left, .tv_nsec = (long)((left - (double)(time_t)left) * 1e9)};
    ppoll(&fd, 1, &ts, NULL);
}

int main(int argc, char** argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: avr_suit ARBITER.hex CLUSTER.hex  (driven by bpms sim --avr)\n");
        return 2;
    }
    // Ctrl-C reaches the whole process group: the Python side decides when to stop ('Q', or
    // the end of stdin when it is gone), so that the final status is always sent.
    signal(SIGINT, SIG_IGN);
    if (read_config()) {
        fprintf(stderr, "avr_suit: incomplete configuration on stdin\n");
        return 2;
    }
    if (board_load(&boards[ARBITER], ARBITER, board_names[ARBITER], argv[1])) return 2;
    board_t* clusters[N_CLUSTERS];
    for (int k = 0; k < N_CLUSTERS; ++k) {
        if (board_load(&boards[1 + k], 1 + k, board_names[1 + k], argv[2])) return 2;
        clusters[k] = &boards[1 + k];
    }
    wires_init(boards);
    chips_init(clusters, &table);
    stats_init(boards);
    fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);

    const double start_wall = wall_now();
    double wall0 = start_wall;  // wall-clock time of simulated time 0 (real-time pacing)
    cycle_t now = 0;
    double status_wall = start_wall;
    cycle_t status_cycle = 0;
    apply_parts(0);
    while (!quit) {
        const cycle_t slice_end = now + SLICE_CYCLES;
        for (cycle_t t = now + QUANTUM; t <= slice_end; t += QUANTUM) {
            for (int i = 0; i < N_BOARDS; ++i) {
                if (board_run(&boards[i], t) < 0) {
                    fprintf(stderr, "avr_suit: the %s core stopped (%s) at %.6f s, pc 0x%04x\n",
                            boards[i].name, board_state_name(&boards[i]), (double)t / F_CPU_HZ,
                            (unsigned)boards[i].avr->pc);
                    send_status(t, wall_now() - start_wall, 0.0, 1);
                    return 3;
                }
            }
            wires_exchange(t);
        }
        now = slice_end;
        apply_parts(now);
        flush_radio();
        handle_input(now);
        if (now - status_cycle >= F_CPU_HZ) {
            const double w = wall_now();
            const double recent = w > status_wall ? (double)(now - status_cycle) / F_CPU_HZ / (w - status_wall) : 0.0;
            send_status(now, w - start_wall, recent, 0);
            status_wall = w;
            status_cycle = now;
        }
        if (config.realtime) {
            // Never ahead of the wall clock. When the host cannot keep up, the suit runs
            // slower (and says so in its factor) instead of bursting to catch up later.
            const double due = wall0 + (double)now / F_CPU_HZ, late = wall_now() - due;
            if (late > MAX_CATCH_UP_S) wall0 += late - MAX_CATCH_UP_S;
            wait_for(due);
        }
    }
    flush_radio();
    const double w = wall_now();
    const double recent = w > status_wall ? (double)(now - status_cycle) / F_CPU_HZ / (w - status_wall) : 0.0;
    send_status(now, w - start_wall, recent, 1);
    return 0;
}

// The serial side of the suit: the arbiter's two 74HC4051 multiplexers (select lines S0..S2 on
// PD2..PD4, the same channel on both), the six cluster USARTs and the RN-41 with its CTS input
// on PD5 (docs/firmware.md, "Wiring assumptions").
//
// Every byte is routed once its stop bit has ended, so the wire knows whether the multiplexer
// stayed on its channel for the whole byte. A byte that was on a wire while the multiplexer
// moved is counted (misrouted / cut) and not delivered, as a real receiver would get garbage.
#include <string.h>

#include <simavr/avr_ioport.h>

#include "suit_host.h"

#define SELECT_HISTORY 64
#define RADIO_BUFFER 65536

static board_t* boards;  // [N_BOARDS]
static wire_counters_t counters;

// changes of the select lines, as (arbiter cycle, channel after the change)
static struct {
    cycle_t at;
    int channel;
} history[SELECT_HISTORY];
static int history_head;  // index of the newest entry
static int select_bits;   // S2 S1 S0
static int cts_high = 1;  // the arbiter's setup() raises CTS before anything else

// The RN-41: host bytes waiting for CTS, and the byte it is sending now.
static uint8_t host_fifo[4096];
static int host_head, host_count;
static int host_inflight;  // 1 while a byte is on the wire to the arbiter
static int host_waiting;   // the next byte is held by CTS (counted once)
static cycle_t host_start, host_end;
static uint8_t host_value;
static const cycle_t rn41_byte_cycles = 160;  // the RN-41 set to 1,000,000 baud 8N1

// bytes the RN-41 received from the arbiter, for the host
static uint8_t radio_buf[RADIO_BUFFER];
static int radio_count;

static cycle_t last_poll_at[N_CLUSTERS];
static int polled_before[N_CLUSTERS];
static cycle_t last_frame_start;
static int frame_started;

static void record_select(cycle_t at) {
    history_head = (history_head + 1) % SELECT_HISTORY;
    history[history_head].at = at;
    history[history_head].channel = select_bits;
}

static void select_pin(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    const int bit = (int)(intptr_t)param;
    const int was = select_bits;
    select_bits = value ? (select_bits | (1 << bit)) : (select_bits & ~(1 << bit));
    if (select_bits != was) record_select(boards[ARBITER].avr->cycle);
}

static void cts_pin(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    (void)param;
    cts_high = value != 0;
}

// The channel selected at cycle t, and whether it stayed selected through `until`.
static int channel_at(cycle_t t) {
    for (int i = 0; i < SELECT_HISTORY; ++i) {
        const int k = (history_head - i + SELECT_HISTORY) % SELECT_HISTORY;
        if (history[k].at <= t) return history[k].channel;
    }
    return history[(history_head + 1) % SELECT_HISTORY].channel;  // older than the history
}

static int changed_between(cycle_t from, cycle_t until) {
    for (int i = 0; i < SELECT_HISTORY; ++i) {
        const int k = (history_head - i + SELECT_HISTORY) % SELECT_HISTORY;
        if (history[k].at <= from) return 0;
        if (history[k].at < until) return 1;
    }
    return 0;
}

void wires_init(board_t b[N_BOARDS]) {
    boards = b;
    memset(&counters, 0, sizeof counters);
    avr_t* arb = b[ARBITER].avr;
    for (int pin = 2; pin <= 4; ++pin)
        avr_irq_register_notify(avr_io_getirq(arb, AVR_IOCTL_IOPORT_GETIRQ('D'), pin),
                                select_pin, (void*)(intptr_t)(pin - 2));
    avr_irq_register_notify(avr_io_getirq(arb, AVR_IOCTL_IOPORT_GETIRQ('D'), 5), cts_pin, NULL);
    // At reset the select lines are inputs pulled high by nothing: the 74HC4051 sees them low.
    select_bits = 0;
    for (int i = 0; i < SELECT_HISTORY; ++i) history[i].at = 0, history[i].channel = 0;
}

static void deliver(board_t* to, cycle_t stop_bit_end, uint8_t value, cycle_t sender_byte) {
    uint16_t v = value;
    // a receiver at another baud rate samples garbage: more than ~4 % apart fails the frame
    const cycle_t a = sender_byte, r = to->byte_cycles;
    if ((a > r ? a - r : r - a) * 100 > 4 * r) {
        v |= UART_INPUT_FE;
        ++counters.framing_errors;
    }
    board_push_event(to, stop_bit_end + QUANTUM, EV_DELIVER, v);
}

static void poll_seen(int cluster, cycle_t at) {
    // a burst of bytes counts as one poll for the cluster firmware; the chips move to the next
    // sample when a byte comes after a pause (a new poll)
    if (!polled_before[cluster] || at - last_poll_at[cluster] > SLICE_CYCLES) {
        chips_poll(cluster, ++counters.polls[cluster]);
        if (cluster == 0 && (!frame_started || at - last_frame_start > CYCLES_PER_FRAME / 2)) {
            ++counters.frames;
            stats_frame_start(at);
            last_frame_start = at;
            frame_started = 1;
        }
    }
    polled_before[cluster] = 1;
    last_poll_at[cluster] = at;
}

static void radio_receive(uint8_t value, cycle_t end) {
    ++counters.radio_bytes_out;
    stats_radio_byte_end(end);
    if (radio_count < RADIO_BUFFER) radio_buf[radio_count++] = value;
}

static void route_arbiter_tx(cycle_t now) {
    board_t* a = &boards[ARBITER];
    while (a->tx_count) {
        tx_byte_t* t = &a->tx[a->tx_head];
        const cycle_t end = t->at + a->byte_cycles;
        if (end > now) break;
        const int ch = channel_at(t->at);
        if (changed_between(t->at, end)) {
            ++counters.misrouted;
        } else if (ch < N_CLUSTERS) {
            deliver(&boards[1 + ch], end, t->value, a->byte_cycles);
            poll_seen(ch, t->at);
        } else if (ch == RADIO_CHANNEL) {
            radio_receive(t->value, end);
        }  // channel 7: pulled up, unused
        a->tx_head = (a->tx_head + 1) % TX_SLOTS;
        --a->tx_count;
    }
}

static void route_cluster_tx(int k, cycle_t now) {
    board_t* c = &boards[1 + k];
    while (c->tx_count) {
        tx_byte_t* t = &c->tx[c->tx_head];
        const cycle_t end = t->at + c->byte_cycles;
        if (end > now) break;
        const int first = channel_at(t->at), last = channel_at(end);
        if (first == k && !changed_between(t->at, end))
            deliver(&boards[ARBITER], end, t->value, c->byte_cycles);
        else if (first == k || last == k)
            ++counters.cut;
        else
            ++counters.unheard;
        c->tx_head = (c->tx_head + 1) % TX_SLOTS;
        --c->tx_count;
    }
}

static void run_rn41(cycle_t now) {
    if (host_inflight && host_end <= now) {
        host_inflight = 0;
        if (channel_at(host_start) == RADIO_CHANNEL && !changed_between(host_start, host_end))
            deliver(&boards[ARBITER], host_end, host_value, rn41_byte_cycles);
        else
            ++counters.host_bytes_lost;  // the arbiter let the radio talk while it listened elsewhere
    }
    if (!host_inflight && host_count) {
        if (cts_high) {
            if (!host_waiting) ++counters.host_bytes_held;
            host_waiting = 1;
            return;
        }
        host_waiting = 0;
        host_value = host_fifo[host_head];
        host_head = (host_head + 1) % (int)sizeof host_fifo;
        --host_count;
        host_inflight = 1;
        host_start = now;
        host_end = now + rn41_byte_cycles;
    }
}

void wires_exchange(cycle_t now) {
    route_arbiter_tx(now);
    for (int k = 0; k < N_CLUSTERS; ++k) route_cluster_tx(k, now);
    run_rn41(now);
}

void wires_host_bytes(const uint8_t* data, int n) {
    for (int i = 0; i < n; ++i) {
        ++counters.host_bytes_in;
        if (host_count == (int)sizeof host_fifo) {  // the radio's buffer is full
            ++counters.host_bytes_lost;
            continue;
        }
        host_fifo[(host_head + host_count) % (int)sizeof host_fifo] = data[i];
        ++host_count;
    }
}

int wires_take_radio(uint8_t* out, int max) {
    int n = radio_count < max ? radio_count : max;
    memcpy(out, radio_buf, (size_t)n);
    memmove(radio_buf, radio_buf + n, (size_t)(radio_count - n));
    radio_count -= n;
    return n;
}

const wire_counters_t* wires_counters(void) { return &counters; }

int wires_arbiter_channel(void) { return select_bits; }

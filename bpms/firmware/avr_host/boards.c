// The seven ATmega328P cores: loading an image, running to a cycle limit with the events of the
// parts in between, and four corrections to simavr 1.6's timing (each written down in
// docs/firmware.md):
//   - a sleeping core wakes for the parts' events instead of skipping to its next timer, and
//     simavr's wall-clock pacing of sleep (usleep) is off: main.c paces the whole suit;
//   - the USART's byte time is 10 bits for 8N1 (simavr counts a parity bit that is not there),
//     and its transmitter is double-buffered as on the chip (simavr 1.6 frees UDR only when
//     the previous byte has left, which leaves a gap of one interrupt latency per byte), and
//     its TXC flag comes when the last byte has left (tx_complete below);
//   - the I2C bus runs at the clock the firmware sets in TWBR/TWSR (simavr's TWI counts one
//     microsecond per bit, 1 MHz): see __wrap_avr_cycle_timer_register_usec below, which also
//     holds a cluster's bus (a stuck SDA) when asked to.
#include <stdio.h>
#include <string.h>

#include <simavr/avr_extint.h>
#include <simavr/sim_core.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_hex.h>
#include <simavr/sim_interrupts.h>

#include "suit_host.h"

static board_t* all_boards[N_BOARDS];

static void no_wall_clock_sleep(avr_t* avr, avr_cycle_count_t how_long) {
    (void)avr;
    (void)how_long;
}

static avr_io_t* find_io(avr_t* avr, const char* kind) {
    for (avr_io_t* io = avr->io_port; io; io = io->next)
        if (io->kind && strcmp(io->kind, kind) == 0) return io;
    return NULL;
}

// TXC as on the chip: set once a byte has left the shift register with none after it.
// simavr 1.6 counts bytes off at the ticks of its transmit pump, which keeps ticking while
// UDRIE is set: a byte written to an empty transmitter just before a tick is counted off at
// once, its TXC raised there and then cleared by the writer itself (Arduino's write clears
// TXC right after UDR), and never raised again, so that HardwareSerial::flush() waited for
// ever. The pump's own flag is left as it is; this one comes when the byte has really left.
static avr_cycle_count_t tx_complete(struct avr_t* avr, avr_cycle_count_t when, void* param) {
    board_t* b = param;
    if (b->tx_free_at <= when && avr_regbit_get(avr, b->uart->txen))
        avr_raise_interrupt(avr, &b->uart->txc);
    return 0;
}

// A byte written to UDR starts on the wire when the shift register is free.
static void uart_output(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    board_t* b = param;
    const cycle_t now = b->avr->cycle;
    const cycle_t start = b->tx_free_at > now ? b->tx_free_at : now;
    b->tx_last_start = start;
    b->tx_free_at = start + b->byte_cycles;
    avr_cycle_timer_register(b->avr, b->tx_free_at - now, tx_complete, b);  // the last one's
    if (b->tx_count == TX_SLOTS) {  // cannot happen: the USART sends one byte per byte time
        ++b->dropped_events;
        return;
    }
    b->tx[(b->tx_head + b->tx_count) % TX_SLOTS] = (tx_byte_t){start, (uint8_t)value};
    ++b->tx_count;
}

// UDR is free again once its byte has moved into the shift register.
static avr_cycle_count_t udr_free(struct avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)when;
    board_t* b = param;
    if (b->uart->tx_cnt == 1 && avr_regbit_get(avr, b->uart->txen))
        avr_raise_interrupt(avr, &b->uart->udrc);
    return 0;
}

// Runs after simavr's own UDR write handler (simavr calls both, in that order).
static void udr_written(struct avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    (void)addr;
    (void)v;
    board_t* b = param;
    if (!avr_regbit_get(avr, b->uart->txen)) return;
    if (b->uart->tx_cnt == 1) {
        udr_free(avr, avr->cycle, b);  // straight into the idle shift register
    } else if (b->uart->tx_cnt == 2) {
        // it waits in UDR until the byte before it has left (simavr counts that byte off one
        // cycle earlier, at the same time)
        avr_cycle_timer_register(avr, b->tx_last_start + 1 - avr->cycle, udr_free, b);
    }
}

int board_load(board_t* b, int index, const char* name, const char* hex_path) {
    memset(b, 0, sizeof *b);
    b->index = index;
    b->name = name;
    b->avr = avr_make_mcu_by_name("atmega328p");
    if (!b->avr) {
        fprintf(stderr, "avr_suit: simavr has no atmega328p core\n");
        return -1;
    }
    avr_init(b->avr);
    b->avr->frequency = F_CPU_HZ;
    b->avr->vcc = b->avr->avcc = b->avr->aref = 3300;  // the boards run at 3.3 V
    b->avr->log = 0;
    b->avr->sleep = no_wall_clock_sleep;
    ihex_chunk_p chunks = NULL;
    int n = read_ihex_chunks(hex_path, &chunks);
    if (n <= 0) {
        fprintf(stderr, "avr_suit: cannot read %s\n", hex_path);
        return -1;
    }
    for (int i = 0; i < n; ++i) {
        if (chunks[i].baseaddr + chunks[i].size > b->avr->flashend + 1u) {
            fprintf(stderr, "avr_suit: %s does not fit the ATmega328P's flash\n", hex_path);
            return -1;
        }
        avr_loadcode(b->avr, chunks[i].data, chunks[i].size, chunks[i].baseaddr);
    }
    free_ihex_chunks(chunks);
    // Pins held low would otherwise be polled every cycle as level-triggered INT0/INT1
    // (the arbiter drives its select lines on PD2/PD3; neither board enables INT0/INT1).
    avr_extint_set_strict_lvl_trig(b->avr, 0, 0);
    avr_extint_set_strict_lvl_trig(b->avr, 1, 0);
    uint32_t flags = 0;  // no usleep while polling, no console echo
    avr_ioctl(b->avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    b->uart = (avr_uart_t*)find_io(b->avr, "uart");
    b->twi = (avr_twi_t*)find_io(b->avr, "twi");
    if (!b->uart || !b->twi) {
        fprintf(stderr, "avr_suit: simavr's atmega328p lacks a USART or TWI\n");
        return -1;
    }
    b->uart_in = avr_io_getirq(b->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(b->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            uart_output, b);
    avr_register_io_write(b->avr, b->uart->r_udr, udr_written, b);
    b->byte_cycles = 160;
    all_boards[index] = b;
    return 0;
}

void board_push_event(board_t* b, cycle_t at, uint8_t kind, uint16_t value) {
    if (b->ev_count == EVENT_SLOTS) {
        ++b->dropped_events;
        return;
    }
    // insert in time order (events come almost always in order: a short backwards walk)
    int i = b->ev_count;
    while (i > 0 && b->ev[(b->ev_head + i - 1) % EVENT_SLOTS].at > at) {
        b->ev[(b->ev_head + i) % EVENT_SLOTS] = b->ev[(b->ev_head + i - 1) % EVENT_SLOTS];
        --i;
    }
    b->ev[(b->ev_head + i) % EVENT_SLOTS] = (core_event_t){at, kind, value};
    ++b->ev_count;
}

int board_rx_unread(const board_t* b) {
    const uart_fifo_t* f = &b->uart->input;
    return ((f->write + uart_fifo_fifo_size) - f->read) & (uart_fifo_fifo_size - 1);
}

static void run_event(board_t* b, const core_event_t* e) {
    if (e->kind == EV_DELIVER) {
        avr_raise_irq(b->uart_in, e->value);
        // simavr makes the byte readable one byte time after it arrives: that is when a real
        // USART completes it. Then two older unread bytes mean the real one overran.
        board_push_event(b, e->at + b->byte_cycles, EV_OVERRUN_CHECK, 0);
    } else if (e->kind == EV_OVERRUN_CHECK) {
        if (board_rx_unread(b) >= 3) ++b->overruns;
    }
}

// simavr's avr_callback_run_raw, with the sleep capped at `cap` and the awake cycles counted.
static void step(board_t* b, cycle_t cap) {
    avr_t* avr = b->avr;
    avr_flashaddr_t new_pc = avr->pc;
    if (avr->state == cpu_Running) {
        const cycle_t c0 = avr->cycle;
        new_pc = avr_run_one(avr);
        b->awake += avr->cycle - c0;
    }
    avr_cycle_count_t sleep = avr_cycle_timer_process(avr);
    avr->pc = new_pc;
    if (avr->state == cpu_Sleeping) {
        if (!avr->sreg[S_I]) {
            avr->state = cpu_Done;  // asleep with interrupts off: nothing can ever wake it
            return;
        }
        cycle_t next = avr->cycle + 1 + sleep;
        if (next > cap) next = cap > avr->cycle ? cap : avr->cycle + 1;
        avr->cycle = next;
    }
    if ((avr->state == cpu_Running || avr->state == cpu_Sleeping) && avr->interrupt_state)
        avr_service_interrupts(avr);
}

int board_run(board_t* b, cycle_t limit) {
    avr_t* avr = b->avr;
    while (avr->cycle < limit) {
        while (b->ev_count && b->ev[b->ev_head].at <= avr->cycle) {
            core_event_t e = b->ev[b->ev_head];
            b->ev_head = (b->ev_head + 1) % EVENT_SLOTS;
            --b->ev_count;
            run_event(b, &e);
        }
        cycle_t cap = limit;
        if (b->ev_count && b->ev[b->ev_head].at < cap) cap = b->ev[b->ev_head].at;
        step(b, cap);
        if (avr->state != cpu_Running && avr->state != cpu_Sleeping) {
            b->crashed = 1;
            return -1;
        }
    }
    return 0;
}

void board_sync_baud(board_t* b) {
    avr_uart_t* u = b->uart;
    avr_t* avr = b->avr;
    const uint32_t ubrr = avr_regbit_get(avr, u->ubrrl) | (avr_regbit_get(avr, u->ubrrh) << 8);
    static const int data_bits[] = {5, 6, 7, 8, 8, 8, 8, 9};
    const int bits = 1 + data_bits[avr_regbit_get(avr, u->ucsz) | (avr_regbit_get(avr, u->ucsz2) << 2)]
                     + 1 + avr_regbit_get(avr, u->usbs);
    // UPM (parity) sits in UCSR0C bits 5..4 on the ATmega328P
    const int parity = (avr->data[u->r_ucsrc] >> 4) & 3 ? 1 : 0;
    cycle_t per_bit = (cycle_t)(ubrr + 1) * (avr_regbit_get(avr, u->u2x) ? 8 : 16);
    cycle_t want = per_bit * (cycle_t)(bits + parity);
    if (u->cycles_per_byte != want) u->cycles_per_byte = want;
    b->byte_cycles = want;
}

const char* board_state_name(const board_t* b) {
    static const char* names[] = {"limbo", "stopped", "running", "sleeping", "step",
                                  "step done", "done", "crashed"};
    int s = b->avr->state;
    return s >= 0 && s < (int)(sizeof names / sizeof *names) ? names[s] : "unknown";
}

// simavr's TWI waits "one microsecond per bit" (its source says so: it ignores the bit rate).
// The firmware sets 400 kHz, 2.5 us per bit. Every TWI delay goes through this function, with
// the TWI as param: scale it to the SCL period the firmware programmed,
// F_CPU / (16 + 2 * TWBR * 4^TWPS).
void __real_avr_cycle_timer_register_usec(struct avr_t* avr, uint32_t when,
                                          avr_cycle_timer_t timer, void* param);
void __wrap_avr_cycle_timer_register_usec(struct avr_t* avr, uint32_t when,
                                          avr_cycle_timer_t timer, void* param) {
    for (int i = 0; i < N_BOARDS; ++i) {
        board_t* b = all_boards[i];
        if (b && b->avr == avr && param == b->twi) {
            if (b->bus_stuck) {  // SDA held low: the START, byte or ACK never completes
                ++b->twi_stalls;
                return;
            }
            const uint8_t twbr = avr->data[b->twi->r_twbr];
            const uint8_t twps = avr_regbit_get(avr, b->twi->twps);
            const cycle_t per_bit = 16u + 2u * twbr * (1u << (2 * twps));
            avr_cycle_timer_register(avr, when * per_bit, timer, param);
            return;
        }
    }
    __real_avr_cycle_timer_register_usec(avr, when, timer, param);
}

// The BPMS suit in simavr: the arbiter and six cluster images, each on a simulated ATmega328P
// at 16 MHz, with the parts around them (docs/firmware.md, "The firmware in a simulator").
//
// One process, one thread: the seven cores run in lock step, QUANTUM cycles at a time, and the
// parts move bytes between them at the quantum boundaries. Python (bpms/firmware/avr_suit.py)
// feeds the sensor values and the host's bytes on stdin and reads the radio's bytes and the
// figures on stdout (bridge.h).
#ifndef BPMS_SUIT_HOST_H
#define BPMS_SUIT_HOST_H

#include <stdint.h>

#include <simavr/sim_avr.h>
#include <simavr/avr_uart.h>
#include <simavr/avr_twi.h>

#define F_CPU_HZ 16000000u
#define N_CLUSTERS 6
#define N_BOARDS (1 + N_CLUSTERS)  // board 0 is the arbiter, 1 + k is cluster k
#define ARBITER 0
#define RADIO_CHANNEL 6             // the RN-41 on both 74HC4051 multiplexers
#define CYCLES_PER_FRAME 320000u    // 20 ms at 16 MHz

// Lock step: every core runs to the next multiple of QUANTUM cycles, then the parts route the
// bytes whose stop bit ended by then. A byte reaches its receiver QUANTUM cycles after its stop
// bit (2 us), so the routing knows whether the multiplexers stayed put for the whole byte.
#define QUANTUM 32u
// The parts' slower bookkeeping (battery, scheduled sensor faults, host bytes, pacing) runs
// once per slice.
#define SLICE_CYCLES 16000u  // 1 ms

typedef uint64_t cycle_t;

// A timed event on one core: a byte to deliver into its USART, or the check of whether the
// byte delivered one byte time earlier would have overrun a real USART's receive buffer.
typedef struct {
    cycle_t at;
    uint8_t kind;  // EV_DELIVER, EV_OVERRUN_CHECK
    uint16_t value;
} core_event_t;
enum { EV_DELIVER = 1, EV_OVERRUN_CHECK = 2 };

#define EVENT_SLOTS 32
#define TX_SLOTS 32

typedef struct {
    cycle_t at;     // cycle at which the firmware wrote UDR (the start bit)
    uint8_t value;
} tx_byte_t;

typedef struct board {
    int index;
    const char* name;
    avr_t* avr;
    avr_uart_t* uart;
    avr_twi_t* twi;
    avr_irq_t* uart_in;
    // bytes the firmware sent, not routed yet (ring)
    tx_byte_t tx[TX_SLOTS];
    int tx_head, tx_count;
    // events, in time order (ring)
    core_event_t ev[EVENT_SLOTS];
    int ev_head, ev_count;
    cycle_t byte_cycles;   // one 8N1 byte at the firmware's baud rate (from its registers)
    cycle_t tx_free_at;    // when the USART's shift register has sent its byte
    cycle_t tx_last_start; // start bit of the byte written last
    cycle_t awake;         // cycles executed (not asleep), since power-up
    uint64_t overruns;     // bytes a real USART would have lost (receive buffer full)
    uint64_t dropped_events;
    int bus_stuck;          // its I2C bus is held: no TWI transfer completes
    uint64_t twi_stalls;    // TWI steps that never completed because of it
    int crashed;
} board_t;

// ---------------------------------------------------------------- boards.c
int board_load(board_t* b, int index, const char* name, const char* hex_path);
// Run the core until its cycle counter reaches `limit` (events on the way are delivered).
// Returns 0, or -1 when the core stopped (crash, sleep with interrupts off).
int board_run(board_t* b, cycle_t limit);
void board_push_event(board_t* b, cycle_t at, uint8_t kind, uint16_t value);
// Keep the byte time in step with the firmware's baud setting (simavr counts a parity bit
// that 8N1 does not have).
void board_sync_baud(board_t* b);
int board_rx_unread(const board_t* b);
const char* board_state_name(const board_t* b);

// ---------------------------------------------------------------- sensor_chips.c
enum { SENSOR_ACCEL = 0, SENSOR_MAG = 1, SENSOR_GYRO = 2 };

typedef struct {
    uint32_t n_samples;
    const int16_t* values;  // [n][18][3 sensors][3 chip axes], chip-axis counts
} motion_table_t;

void chips_init(board_t* clusters[N_CLUSTERS], const motion_table_t* table);
// Cluster k received poll number `poll` (from 1): its chips now show motion sample poll - 1.
// So the reading taken after poll p carries sample p - 1, and the power-up reading (before any
// poll) is all zeros, like the Python suit's first stale frame.
void chips_poll(int cluster, uint64_t poll);
void chips_power(int imu, int sensor, int on);
int chips_powered(int imu, int sensor);
uint64_t chips_i2c_bytes(int cluster);
uint64_t chips_nacks(int cluster);

// ---------------------------------------------------------------- serial_mux.c
typedef struct {
    uint64_t frames;            // poll rounds (frame starts) since power-up
    uint64_t misrouted;         // arbiter bytes on the wire while its multiplexer moved
    uint64_t cut;               // cluster or host bytes cut short by a multiplexer switch
    uint64_t unheard;           // cluster bytes sent while the arbiter listened elsewhere
    uint64_t host_bytes_in;     // host bytes handed to the RN-41
    uint64_t host_bytes_lost;   // host bytes that never reached the arbiter's USART: sent
                                // while it listened elsewhere, or beyond the RN-41's buffer
    uint64_t host_bytes_held;   // host bytes the RN-41 kept until CTS let it send them
    uint64_t radio_bytes_out;   // bytes that reached the RN-41 (to the host)
    uint64_t framing_errors;    // bytes between boards at different baud rates
    uint64_t polls[N_CLUSTERS];
} wire_counters_t;

void wires_init(board_t boards[N_BOARDS]);
// Route the bytes whose stop bit ended by `now` (every core is at `now`).
void wires_exchange(cycle_t now);
// Host bytes for the RN-41 (sent to the arbiter as CTS allows).
void wires_host_bytes(const uint8_t* data, int n);
// Bytes the RN-41 received from the arbiter since the last call (for the host).
int wires_take_radio(uint8_t* out, int max);
const wire_counters_t* wires_counters(void);
int wires_arbiter_channel(void);

// ---------------------------------------------------------------- frame_stats.c
void stats_init(board_t boards[N_BOARDS]);
void stats_frame_start(cycle_t at);         // the arbiter polled cluster 0 after a pause
void stats_radio_byte_end(cycle_t at);      // a byte reached the RN-41
void stats_write_json(char* out, int size, cycle_t now, double wall_s, double recent_factor,
                      board_t boards[N_BOARDS], int final);

#endif  // BPMS_SUIT_HOST_H

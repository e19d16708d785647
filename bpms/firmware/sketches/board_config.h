// Wiring and link settings of the BPMS boards (docs/firmware.md, "Wiring assumptions").
#ifndef BPMS_BOARD_CONFIG_H
#define BPMS_BOARD_CONFIG_H

// Every UART in the suit (arbiter <-> clusters, arbiter <-> RN-41) runs at 1,000,000 baud:
// exact at 16 MHz with U2X (UBRR = 1). The RN-41 is set to it once with "SZ,4096".
#define BPMS_BAUD 1000000UL

// I2C clock of the cluster boards (all three chips and the TCA9548A support 400 kHz).
#define BPMS_I2C_HZ 400000UL
// Wire gives up (and resets the TWI unit) after this long on a stuck bus.
#define BPMS_I2C_TIMEOUT_US 3000UL

// Cluster board pins.
#define CLUSTER_ERROR_LED_PIN 13

// Arbiter board pins: 74HC4051 select lines S0..S2 (shared by both multiplexers), the RN-41
// CTS input (HIGH = hold), the battery divider and the streaming LED.
#define ARBITER_SEL0_PIN 2
#define ARBITER_SEL1_PIN 3
#define ARBITER_SEL2_PIN 4
#define ARBITER_RADIO_CTS_PIN 5
#define ARBITER_BATTERY_PIN A0
#define ARBITER_STREAM_LED_PIN 13

#endif  // BPMS_BOARD_CONFIG_H

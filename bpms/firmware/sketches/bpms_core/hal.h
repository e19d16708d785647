// Hardware abstraction used by the shared logic. The sketches implement it on the Arduino core
// (HardwareSerial, Wire, digital pins, ADC); the host build implements it with fakes.
//
// Destructors are protected and non-virtual: objects are never deleted through these
// interfaces (no heap on the AVR), which keeps operator delete out of the firmware.
#ifndef BPMS_HAL_H
#define BPMS_HAL_H

#include <stdint.h>

namespace bpms {

class Clock {
public:
    virtual uint32_t micros() = 0;               // wrapping 32-bit microsecond counter
    virtual void delay_micros(uint16_t us) = 0;  // busy wait
protected:
    ~Clock() {}
};

// A byte-oriented serial port (the ATmega328P's single USART).
class SerialPort {
public:
    virtual int available() = 0;                         // bytes waiting in the RX buffer
    virtual int read() = 0;                              // next byte, or -1 when empty
    virtual void write(const uint8_t* data, uint16_t n) = 0;  // may return before sent
    virtual void flush() = 0;                            // wait until every byte is on the wire
    // Sleep (CPU idle mode: the USART and the timers keep running) until the next interrupt:
    // a received or transmitted byte, or the 1.024 ms timer tick behind micros(). Returns at
    // once when a received byte is already waiting (checked with interrupts off, so a byte
    // that arrives just before the sleep still wakes it).
    virtual void idle() = 0;
protected:
    ~SerialPort() {}
};

// I2C master. Register-level helpers are built on these two primitives in sensors.h.
class I2cBus {
public:
    // Write n bytes to a 7-bit address; true when every byte was acknowledged.
    virtual bool write(uint8_t addr, const uint8_t* data, uint8_t n) = 0;
    // Read n bytes; returns how many arrived (fewer, or 0, when the device did not answer).
    virtual uint8_t read(uint8_t addr, uint8_t* data, uint8_t n) = 0;
protected:
    ~I2cBus() {}
};

class DigitalOut {
public:
    virtual void set(bool on) = 0;
protected:
    ~DigitalOut() {}
};

// The arbiter's board: two 74HC4051 8:1 analogue multiplexers with shared select lines route
// the USART to one cluster (channels 0..5) or to the RN-41 (channel RADIO); the RN-41's CTS
// input lets the arbiter hold the host's bytes inside the radio while it talks to a cluster.
class ArbiterBoard {
public:
    static const uint8_t RADIO = 6;
    virtual void select_channel(uint8_t channel) = 0;  // 0..5 cluster, RADIO
    virtual void hold_radio(bool hold) = 0;            // true: RN-41 must not send to us
    virtual uint16_t read_battery_adc() = 0;           // one 10-bit conversion
protected:
    ~ArbiterBoard() {}
};

}  // namespace bpms

#endif  // BPMS_HAL_H

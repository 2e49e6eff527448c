/* rhi_device.h: the device side of the rhi device protocol v1.1 (wire version 2), in C99 + POSIX sockets.
 *
 * docs/protocol.md is the contract; this kit implements it for a device written in C:
 *   - pack and parse every message (HELLO, INFO, COMMAND, READING, ERROR), little-endian on any host;
 *   - sessions: a HELLO opens one, a second host is refused (ERROR/BUSY) unless it asks to take over,
 *     and then the old host is told (ERROR/SESSION_LOST); BYE or `session_timeout` without a valid
 *     command ends a session; every new session starts its readings at seq 0 with nothing echoed;
 *   - commands: only the session's host and id, newer sequence numbers (duplicates and older ones are
 *     ignored), no reserved flag bit, finite torques (of any size: they are clamped);
 *   - the watchdog (zero torque `watchdog` s after the last valid command), ESTOP/RESET, a latched FAULT.
 *
 * A device's loop, once per period 1/rate on the monotonic clock (see rhi_ref_device.c):
 *     rhi_device_send_reading(&d, t, q, dq, s);     // sample, then send
 *     rhi_device_poll(&d, deadline - rhi_now());    // take the commands that arrive until the next period
 *     rhi_device_torque(&d, rhi_now(), tau);        // the torque to apply now: clamped, or zeros
 *     apply(tau);
 */
#ifndef RHI_DEVICE_H
#define RHI_DEVICE_H

#include <netinet/in.h>
#include <stddef.h>
#include <stdint.h>

#define RHI_WIRE_VERSION 2u /* protocol v1.1; v1.0 sent 1 */
#define RHI_V1_0 1u
#define RHI_MAX_N 32
#define RHI_MAX_K 64
#define RHI_NO_SEQ 0xFFFFFFFFu

/* COMMAND flags (bits 4..15 reserved: a command with one of them set is invalid) */
#define RHI_ENABLE 1u
#define RHI_ESTOP 2u
#define RHI_RESET 4u
#define RHI_BYE 8u
#define RHI_COMMAND_FLAGS 15u
/* READING status flags */
#define RHI_ENABLED 1u
#define RHI_ST_ESTOP 2u
#define RHI_WATCHDOG 4u
#define RHI_FAULT 8u
#define RHI_SIMULATED 16u
/* HELLO flags */
#define RHI_TAKEOVER 1u
/* ERROR codes */
#define RHI_E_VERSION 1u
#define RHI_E_HELLO 2u
#define RHI_E_BUSY 3u
#define RHI_E_SESSION_LOST 4u

/* sizes of the fixed parts [bytes] */
#define RHI_HELLO_SIZE 16u
#define RHI_INFO_SIZE 36u
#define RHI_COMMAND_SIZE 36u
#define RHI_READING_SIZE 36u
#define RHI_ERROR_SIZE 16u

/* ------------------------------------------------------------------------------------------- messages */
typedef struct {
    uint16_t flags;
    uint64_t session;
} rhi_hello;

typedef struct {
    uint16_t n, k;
    double rate, watchdog; /* [Hz], [s] */
    uint64_t session;
    const char *json; /* points into the datagram; json_len bytes, not NUL-terminated */
    size_t json_len;
} rhi_info;

typedef struct {
    uint16_t flags;
    uint64_t session;
    uint32_t seq, ack;
    uint16_t n;
    double t_host;          /* [s] */
    double tau[RHI_MAX_N];  /* [N m] */
} rhi_command;

typedef struct {
    uint16_t status;
    uint64_t session;
    uint32_t seq, cmd_seq;
    uint16_t n, k;
    double t_dev;                  /* [s] */
    double q[RHI_MAX_N], dq[RHI_MAX_N]; /* [rad], [rad/s] */
    double s[RHI_MAX_K];
} rhi_reading;

typedef struct {
    uint16_t version, code;
    uint64_t session;
    const char *message; /* points into the datagram, message_len bytes */
    size_t message_len;
} rhi_error;

/* pack: bytes written, 0 when `cap` is too small or an argument is out of range */
size_t rhi_pack_hello(uint8_t *buf, size_t cap, uint64_t session, uint16_t flags);
size_t rhi_pack_info(uint8_t *buf, size_t cap, uint16_t n, uint16_t k, double rate, double watchdog,
                     uint64_t session, const char *json);
size_t rhi_pack_command(uint8_t *buf, size_t cap, const rhi_command *c);
size_t rhi_pack_reading(uint8_t *buf, size_t cap, const rhi_reading *r);
size_t rhi_pack_error(uint8_t *buf, size_t cap, uint16_t code, uint64_t session, const char *msg);
size_t rhi_pack_error_v1_0(uint8_t *buf, size_t cap, const char *msg);

/* parse: 0 when valid, -1 otherwise (`why`, when not NULL, says why for HELLO) */
int rhi_parse_hello(const uint8_t *buf, size_t len, rhi_hello *out, char *why, size_t why_cap);
int rhi_parse_info(const uint8_t *buf, size_t len, rhi_info *out);
int rhi_parse_command(const uint8_t *buf, size_t len, uint16_t n, rhi_command *out);
int rhi_parse_reading(const uint8_t *buf, size_t len, uint16_t n, uint16_t k, rhi_reading *out);
int rhi_parse_error(const uint8_t *buf, size_t len, rhi_error *out);

/* whether sequence number `seq` follows `last` (u32 serial-number arithmetic: 1 <= seq - last < 2^31) */
int rhi_seq_newer(uint32_t seq, uint32_t last);
/* the monotonic clock [s] */
double rhi_now(void);

/* ----------------------------------------------------------------------------------- the device side */
typedef struct {
    const char *name;          /* INFO "device": the host matches it against its configuration */
    uint16_t n;                /* motors */
    double rate;               /* readings per second [Hz] */
    double watchdog;           /* zero torque this long after the last valid command [s] (rhi: 0.02) */
    double session_timeout;    /* a session without a valid command this long ends [s] (rhi: 1.0) */
    const double *tau_min, *tau_max;  /* (n,) torque limits [N m]: every command is clamped into them */
    uint16_t n_sensors;        /* sensor blocks of each READING, in order */
    const char *const *sensor_names;
    const uint16_t *sensor_widths;
    const char *const *joint_names; /* (n,) or NULL */
    uint16_t status_bits;      /* set in every reading, e.g. RHI_SIMULATED */
} rhi_config;

typedef struct {
    unsigned long readings, commands, invalid, foreign, stale_commands, refused, takeovers, watchdog_trips,
        sessions;
} rhi_stats;

typedef struct {
    rhi_config cfg;
    uint16_t k;
    int sock;
    char info_json[4096];
    /* the session */
    int active;
    uint64_t session;
    struct sockaddr_in client;
    uint32_t seq;        /* the next reading's */
    int have_cmd;        /* a valid command was taken in this session (the watchdog is armed) */
    uint32_t cmd_seq;    /* the last command taken */
    uint16_t cmd_flags;
    double tau_cmd[RHI_MAX_N];
    double last_valid;   /* rhi_now() of the HELLO or of the last valid command */
    /* latched state */
    int estop, fault, watchdog, enabled;
    rhi_stats stats;
    char event[256];     /* the newest session event (opened, refused, taken over, BYE, timeout), for a log */
    unsigned long events;
} rhi_device;

/* Bind UDP host:port (port 0: any free one; rhi_device_port says which). 0, or -1 with errno set. */
int rhi_device_open(rhi_device *d, const rhi_config *cfg, const char *host, uint16_t port);
uint16_t rhi_device_port(const rhi_device *d);
/* Handle every waiting datagram, waiting up to `timeout` [s] for the first. Returns the number handled. */
int rhi_device_poll(rhi_device *d, double timeout);
/* Whether a session is open (readings go to its host). */
int rhi_device_active(const rhi_device *d);
/* Send one READING to the session's host (nothing without a session): t_dev [s], q, dq (n,), s (k,). */
int rhi_device_send_reading(rhi_device *d, double t_dev, const double *q, const double *dq, const double *s);
/* The torque to apply at `now` into tau (n,): the last command clamped into the limits, or zeros (watchdog,
 * not enabled, ESTOP, FAULT, no session). Returns 1 when the motors are enabled. Ends a timed-out session. */
int rhi_device_torque(rhi_device *d, double now, double *tau);
/* Latch a device fault (zero torque and FAULT in every reading until the process restarts). */
void rhi_device_fault(rhi_device *d);
void rhi_device_close(rhi_device *d);

#endif

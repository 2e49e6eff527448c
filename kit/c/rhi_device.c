/* rhi_device.c: the rhi device protocol v1.1 for a device written in C (see rhi_device.h, docs/protocol.md). */
#define _POSIX_C_SOURCE 200809L

#include "rhi_device.h"

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------------- little-endian fields on any host */
static void put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put_u32(uint8_t *p, uint32_t v) { int i; for (i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void put_u64(uint8_t *p, uint64_t v) { int i; for (i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void put_f64(uint8_t *p, double v) { uint64_t u; memcpy(&u, &v, 8); put_u64(p, u); }
static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t get_u32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static uint64_t get_u64(const uint8_t *p) { return (uint64_t)get_u32(p) | ((uint64_t)get_u32(p + 4) << 32); }
static double get_f64(const uint8_t *p) { uint64_t u = get_u64(p); double v; memcpy(&v, &u, 8); return v; }

static void head(uint8_t *p, const char *magic, uint16_t version, uint16_t field) {
    memcpy(p, magic, 4);
    put_u16(p + 4, version);
    put_u16(p + 6, field);
}

static int is(const uint8_t *buf, size_t len, const char *magic) { return len >= 8 && memcmp(buf, magic, 4) == 0; }

/* ------------------------------------------------------------------------------------------ messages */
size_t rhi_pack_hello(uint8_t *buf, size_t cap, uint64_t session, uint16_t flags) {
    if (cap < RHI_HELLO_SIZE) return 0;
    head(buf, "RHIH", RHI_WIRE_VERSION, flags);
    put_u64(buf + 8, session);
    return RHI_HELLO_SIZE;
}

size_t rhi_pack_info(uint8_t *buf, size_t cap, uint16_t n, uint16_t k, double rate, double watchdog,
                     uint64_t session, const char *json) {
    size_t m = strlen(json);
    if (cap < RHI_INFO_SIZE + m) return 0;
    head(buf, "RHII", RHI_WIRE_VERSION, n);
    put_u16(buf + 8, k);
    put_u16(buf + 10, 0);
    put_f64(buf + 12, rate);
    put_f64(buf + 20, watchdog);
    put_u64(buf + 28, session);
    memcpy(buf + RHI_INFO_SIZE, json, m);
    return RHI_INFO_SIZE + m;
}

size_t rhi_pack_command(uint8_t *buf, size_t cap, const rhi_command *c) {
    size_t size = RHI_COMMAND_SIZE + 8u * c->n, i;
    if (c->n > RHI_MAX_N || cap < size) return 0;
    head(buf, "RHIC", RHI_WIRE_VERSION, c->flags);
    put_u64(buf + 8, c->session);
    put_u32(buf + 16, c->seq);
    put_u32(buf + 20, c->ack);
    put_u16(buf + 24, c->n);
    put_u16(buf + 26, 0);
    put_f64(buf + 28, c->t_host);
    for (i = 0; i < c->n; i++) put_f64(buf + RHI_COMMAND_SIZE + 8 * i, c->tau[i]);
    return size;
}

size_t rhi_pack_reading(uint8_t *buf, size_t cap, const rhi_reading *r) {
    size_t size = RHI_READING_SIZE + 8u * (2u * r->n + r->k), i;
    uint8_t *p = buf + RHI_READING_SIZE;
    if (r->n > RHI_MAX_N || r->k > RHI_MAX_K || cap < size) return 0;
    head(buf, "RHIR", RHI_WIRE_VERSION, r->status);
    put_u64(buf + 8, r->session);
    put_u32(buf + 16, r->seq);
    put_u32(buf + 20, r->cmd_seq);
    put_u16(buf + 24, r->n);
    put_u16(buf + 26, r->k);
    put_f64(buf + 28, r->t_dev);
    for (i = 0; i < r->n; i++) put_f64(p + 8 * i, r->q[i]);
    for (i = 0; i < r->n; i++) put_f64(p + 8 * (r->n + i), r->dq[i]);
    for (i = 0; i < r->k; i++) put_f64(p + 8 * (2u * r->n + i), r->s[i]);
    return size;
}

size_t rhi_pack_error(uint8_t *buf, size_t cap, uint16_t code, uint64_t session, const char *msg) {
    size_t m = strlen(msg);
    if (m > 1000) m = 1000;
    if (cap < RHI_ERROR_SIZE + m) return 0;
    head(buf, "RHIE", RHI_WIRE_VERSION, code);
    put_u64(buf + 8, session);
    memcpy(buf + RHI_ERROR_SIZE, msg, m);
    return RHI_ERROR_SIZE + m;
}

size_t rhi_pack_error_v1_0(uint8_t *buf, size_t cap, const char *msg) {
    size_t m = strlen(msg);
    if (m > 1000) m = 1000;
    if (cap < 8 + m) return 0;
    head(buf, "RHIE", RHI_V1_0, 0);
    memcpy(buf + 8, msg, m);
    return 8 + m;
}

int rhi_parse_hello(const uint8_t *buf, size_t len, rhi_hello *out, char *why, size_t why_cap) {
    uint16_t version;
    char tmp[160];
    if (!is(buf, len, "RHIH")) return -1;
    version = get_u16(buf + 4);
    tmp[0] = 0;
    if (version != RHI_WIRE_VERSION)
        snprintf(tmp, sizeof tmp, "protocol version %u not supported; this device speaks v1.1 (wire version %u)",
                 (unsigned)version, RHI_WIRE_VERSION);
    else if (len != RHI_HELLO_SIZE)
        snprintf(tmp, sizeof tmp, "HELLO of %lu bytes; v1.1 HELLO is exactly %u bytes", (unsigned long)len,
                 RHI_HELLO_SIZE);
    else if (get_u64(buf + 8) == 0)
        snprintf(tmp, sizeof tmp, "HELLO with session id 0; draw a random non-zero u64");
    else if (get_u16(buf + 6) & ~RHI_TAKEOVER)
        snprintf(tmp, sizeof tmp, "HELLO with unknown flag bits 0x%04x", (unsigned)(get_u16(buf + 6) & ~RHI_TAKEOVER));
    if (tmp[0]) {
        if (why && why_cap) snprintf(why, why_cap, "%s", tmp);
        return -1;
    }
    out->flags = get_u16(buf + 6);
    out->session = get_u64(buf + 8);
    return 0;
}

int rhi_parse_info(const uint8_t *buf, size_t len, rhi_info *out) {
    if (!is(buf, len, "RHII") || get_u16(buf + 4) != RHI_WIRE_VERSION || len < RHI_INFO_SIZE) return -1;
    out->n = get_u16(buf + 6);
    out->k = get_u16(buf + 8);
    out->rate = get_f64(buf + 12);
    out->watchdog = get_f64(buf + 20);
    out->session = get_u64(buf + 28);
    out->json = (const char *)buf + RHI_INFO_SIZE;
    out->json_len = len - RHI_INFO_SIZE;
    return 0;
}

int rhi_parse_command(const uint8_t *buf, size_t len, uint16_t n, rhi_command *out) {
    size_t i;
    if (n > RHI_MAX_N || !is(buf, len, "RHIC") || len != RHI_COMMAND_SIZE + 8u * n) return -1;
    if (get_u16(buf + 4) != RHI_WIRE_VERSION || get_u16(buf + 24) != n) return -1;
    out->flags = get_u16(buf + 6);
    if (out->flags & ~RHI_COMMAND_FLAGS) return -1;
    out->session = get_u64(buf + 8);
    out->seq = get_u32(buf + 16);
    out->ack = get_u32(buf + 20);
    out->n = n;
    out->t_host = get_f64(buf + 28);
    for (i = 0; i < n; i++) {
        out->tau[i] = get_f64(buf + RHI_COMMAND_SIZE + 8 * i);
        if (!isfinite(out->tau[i])) return -1; /* finite values of any size are valid: the device clamps them */
    }
    return 0;
}

int rhi_parse_reading(const uint8_t *buf, size_t len, uint16_t n, uint16_t k, rhi_reading *out) {
    size_t i;
    const uint8_t *p = buf + RHI_READING_SIZE;
    if (n > RHI_MAX_N || k > RHI_MAX_K || !is(buf, len, "RHIR") || len != RHI_READING_SIZE + 8u * (2u * n + k))
        return -1;
    if (get_u16(buf + 4) != RHI_WIRE_VERSION || get_u16(buf + 24) != n || get_u16(buf + 26) != k) return -1;
    out->status = get_u16(buf + 6);
    out->session = get_u64(buf + 8);
    out->seq = get_u32(buf + 16);
    out->cmd_seq = get_u32(buf + 20);
    out->n = n;
    out->k = k;
    out->t_dev = get_f64(buf + 28);
    for (i = 0; i < n; i++) out->q[i] = get_f64(p + 8 * i);
    for (i = 0; i < n; i++) out->dq[i] = get_f64(p + 8 * (n + i));
    for (i = 0; i < k; i++) out->s[i] = get_f64(p + 8 * (2u * n + i));
    return 0;
}

int rhi_parse_error(const uint8_t *buf, size_t len, rhi_error *out) {
    if (!is(buf, len, "RHIE")) return -1;
    out->version = get_u16(buf + 4);
    if (out->version == RHI_WIRE_VERSION && len >= RHI_ERROR_SIZE) {
        out->code = get_u16(buf + 6);
        out->session = get_u64(buf + 8);
        out->message = (const char *)buf + RHI_ERROR_SIZE;
        out->message_len = len - RHI_ERROR_SIZE;
    } else {
        out->code = 0;
        out->session = 0;
        out->message = (const char *)buf + 8;
        out->message_len = len - 8;
    }
    return 0;
}

int rhi_seq_newer(uint32_t seq, uint32_t last) {
    uint32_t d = seq - last; /* unsigned: wraps */
    return d != 0 && d < 0x80000000u;
}

double rhi_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ------------------------------------------------------------------------------------- the device side */
static int json_string(char *out, size_t cap, const char *s) {
    size_t j = 0;
    if (cap < 3) return -1;
    out[j++] = '"';
    for (; *s; s++) {
        if (j + 8 >= cap) return -1;
        if (*s == '"' || *s == '\\') { out[j++] = '\\'; out[j++] = *s; }
        else if ((unsigned char)*s < 0x20) j += (size_t)snprintf(out + j, cap - j, "\\u%04x", (unsigned)*s);
        else out[j++] = *s;
    }
    out[j++] = '"';
    out[j] = 0;
    return (int)j;
}

/* INFO's JSON: device, sensors, joint_names, torque_min, torque_max */
static int build_info(rhi_device *d) {
    char *o = d->info_json, tmp[256];
    size_t cap = sizeof d->info_json, j = 0, i;
    const rhi_config *c = &d->cfg;
#define ADD(...) do { int w_ = snprintf(o + j, cap - j, __VA_ARGS__); if (w_ < 0 || (size_t)w_ >= cap - j) return -1; \
                      j += (size_t)w_; } while (0)
    if (json_string(tmp, sizeof tmp, c->name) < 0) return -1;
    ADD("{\"device\": %s, \"sensors\": [", tmp);
    for (i = 0; i < c->n_sensors; i++) {
        if (json_string(tmp, sizeof tmp, c->sensor_names[i]) < 0) return -1;
        ADD("%s[%s, %u]", i ? ", " : "", tmp, (unsigned)c->sensor_widths[i]);
    }
    ADD("]");
    if (c->joint_names) {
        ADD(", \"joint_names\": [");
        for (i = 0; i < c->n; i++) {
            if (json_string(tmp, sizeof tmp, c->joint_names[i]) < 0) return -1;
            ADD("%s%s", i ? ", " : "", tmp);
        }
        ADD("]");
    }
    ADD(", \"torque_min\": [");
    for (i = 0; i < c->n; i++) ADD("%s%.17g", i ? ", " : "", c->tau_min[i]);
    ADD("], \"torque_max\": [");
    for (i = 0; i < c->n; i++) ADD("%s%.17g", i ? ", " : "", c->tau_max[i]);
    ADD("]}");
#undef ADD
    return 0;
}

int rhi_device_open(rhi_device *d, const rhi_config *cfg, const char *host, uint16_t port) {
    struct sockaddr_in a;
    size_t i;
    int buf = 1 << 20;
    memset(d, 0, sizeof *d);
    d->sock = -1;
    if (!cfg || !cfg->name || cfg->n == 0 || cfg->n > RHI_MAX_N || !(cfg->rate > 0) || !(cfg->watchdog > 0)
        || !(cfg->session_timeout > 0) || !cfg->tau_min || !cfg->tau_max) {
        errno = EINVAL;
        return -1;
    }
    d->cfg = *cfg;
    for (i = 0; i < cfg->n_sensors; i++) d->k = (uint16_t)(d->k + cfg->sensor_widths[i]);
    for (i = 0; i < cfg->n; i++)
        if (!(cfg->tau_min[i] <= 0 && cfg->tau_max[i] >= 0)) { errno = EINVAL; return -1; }
    if (d->k > RHI_MAX_K || build_info(d) < 0) { errno = EINVAL; return -1; }
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    if (inet_pton(AF_INET, host, &a.sin_addr) != 1) { errno = EINVAL; return -1; }
    d->sock = socket(AF_INET, SOCK_DGRAM, 0);
    if (d->sock < 0) return -1;
    setsockopt(d->sock, SOL_SOCKET, SO_RCVBUF, &buf, sizeof buf);
    if (bind(d->sock, (struct sockaddr *)&a, sizeof a) < 0) {
        close(d->sock);
        d->sock = -1;
        return -1;
    }
    d->cmd_seq = RHI_NO_SEQ;
    return 0;
}

uint16_t rhi_device_port(const rhi_device *d) {
    struct sockaddr_in a;
    socklen_t n = sizeof a;
    if (getsockname(d->sock, (struct sockaddr *)&a, &n) < 0) return 0;
    return ntohs(a.sin_port);
}

static void send_to(rhi_device *d, const uint8_t *pkt, size_t len, const struct sockaddr_in *to) {
    if (len) sendto(d->sock, pkt, len, 0, (const struct sockaddr *)to, sizeof *to);
}

static int same_addr(const struct sockaddr_in *a, const struct sockaddr_in *b) {
    return a->sin_addr.s_addr == b->sin_addr.s_addr && a->sin_port == b->sin_port;
}

static void note(rhi_device *d, const char *what, const struct sockaddr_in *who) {
    char ip[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &who->sin_addr, ip, sizeof ip);
    snprintf(d->event, sizeof d->event, "%s %s:%u", what, ip, (unsigned)ntohs(who->sin_port));
    d->events++;
}

static void end_session(rhi_device *d, const char *why) {
    if (d->active) note(d, why, &d->client);
    d->active = 0;
    d->have_cmd = 0;
    d->enabled = 0;
}

static void on_hello(rhi_device *d, const uint8_t *pkt, size_t len, const struct sockaddr_in *from, double now) {
    uint8_t out[RHI_INFO_SIZE + sizeof d->info_json];
    char why[200];
    rhi_hello h;
    if (len >= 8 && get_u16(pkt + 4) == RHI_V1_0) { /* a v1.0 host: refused in its own layout, so it can print it */
        d->stats.refused++;
        send_to(d, out, rhi_pack_error_v1_0(out, sizeof out, "protocol v1.0 is not served: this device speaks "
                                            "v1.1 (wire version 2, docs/protocol.md); update the host"), from);
        return;
    }
    if (rhi_parse_hello(pkt, len, &h, why, sizeof why) < 0) {
        d->stats.refused++;
        send_to(d, out, rhi_pack_error(out, sizeof out, get_u16(pkt + 4) != RHI_WIRE_VERSION ? RHI_E_VERSION
                                       : RHI_E_HELLO, 0, why), from);
        return;
    }
    if (d->active && h.session == d->session && same_addr(from, &d->client)) { /* repeated HELLO: INFO again */
        send_to(d, out, rhi_pack_info(out, sizeof out, d->cfg.n, d->k, d->cfg.rate, d->cfg.watchdog, d->session,
                                      d->info_json), from);
        return;
    }
    if (d->active && now - d->last_valid <= d->cfg.session_timeout) {
        char msg[200], ip[INET_ADDRSTRLEN];
        if (!(h.flags & RHI_TAKEOVER)) {
            d->stats.refused++;
            inet_ntop(AF_INET, &d->client.sin_addr, ip, sizeof ip);
            snprintf(msg, sizeof msg, "device busy: a session of %s:%u is active; HELLO with TAKEOVER ends it", ip,
                     (unsigned)ntohs(d->client.sin_port));
            send_to(d, out, rhi_pack_error(out, sizeof out, RHI_E_BUSY, h.session, msg), from);
            note(d, "refused (busy)", from);
            return;
        }
        d->stats.takeovers++;
        inet_ntop(AF_INET, &from->sin_addr, ip, sizeof ip);
        snprintf(msg, sizeof msg, "the device was taken over by %s:%u", ip, (unsigned)ntohs(from->sin_port));
        send_to(d, out, rhi_pack_error(out, sizeof out, RHI_E_SESSION_LOST, d->session, msg), &d->client);
        end_session(d, "session taken over from");
    }
    d->active = 1;
    d->session = h.session;
    d->client = *from;
    d->seq = 0;
    d->have_cmd = 0;
    d->cmd_seq = RHI_NO_SEQ;
    d->enabled = 0;
    d->watchdog = 0;
    d->last_valid = now;
    d->stats.sessions++;
    note(d, "session opened by", from);
    send_to(d, out, rhi_pack_info(out, sizeof out, d->cfg.n, d->k, d->cfg.rate, d->cfg.watchdog, d->session,
                                  d->info_json), from);
}

static void on_command(rhi_device *d, const uint8_t *pkt, size_t len, const struct sockaddr_in *from, double now) {
    rhi_command c;
    if (rhi_parse_command(pkt, len, d->cfg.n, &c) < 0) { d->stats.invalid++; return; }
    if (!d->active || c.session != d->session || !same_addr(from, &d->client)) { d->stats.foreign++; return; }
    if (d->have_cmd && !rhi_seq_newer(c.seq, d->cmd_seq)) { d->stats.stale_commands++; return; }
    d->stats.commands++;
    d->have_cmd = 1;
    d->cmd_seq = c.seq;
    d->last_valid = now;
    d->watchdog = 0;
    if (c.flags & RHI_BYE) { end_session(d, "BYE from"); return; }
    if (c.flags & RHI_ESTOP) d->estop = 1;
    if (c.flags & RHI_RESET) d->estop = 0;
    d->cmd_flags = c.flags;
    memcpy(d->tau_cmd, c.tau, sizeof(double) * d->cfg.n);
}

int rhi_device_poll(rhi_device *d, double timeout) {
    uint8_t pkt[65536];
    int handled = 0;
    for (;;) {
        struct sockaddr_in from;
        socklen_t fl = sizeof from;
        ssize_t len;
        double now;
        if (timeout > 0) {
            fd_set rd;
            struct timeval tv;
            FD_ZERO(&rd);
            FD_SET(d->sock, &rd);
            tv.tv_sec = (time_t)timeout;
            tv.tv_usec = (suseconds_t)((timeout - (double)tv.tv_sec) * 1e6);
            if (select(d->sock + 1, &rd, NULL, NULL, &tv) <= 0) return handled;
            timeout = 0;
        }
        len = recvfrom(d->sock, pkt, sizeof pkt, MSG_DONTWAIT, (struct sockaddr *)&from, &fl);
        if (len < 0) {
            if (errno == EAGAIN || errno == EWOULDBLOCK) return handled;
            continue; /* e.g. ICMP from a host that went away */
        }
        now = rhi_now();
        handled++;
        if (is(pkt, (size_t)len, "RHIH")) on_hello(d, pkt, (size_t)len, &from, now);
        else if (is(pkt, (size_t)len, "RHIC")) on_command(d, pkt, (size_t)len, &from, now);
        else d->stats.invalid++; /* unknown magic: ignored */
    }
}

int rhi_device_active(const rhi_device *d) { return d->active; }

int rhi_device_send_reading(rhi_device *d, double t_dev, const double *q, const double *dq, const double *s) {
    uint8_t pkt[RHI_READING_SIZE + 8 * (2 * RHI_MAX_N + RHI_MAX_K)];
    rhi_reading r;
    size_t len;
    if (!d->active) return 0;
    r.status = (uint16_t)(d->cfg.status_bits | (d->enabled ? RHI_ENABLED : 0) | (d->estop ? RHI_ST_ESTOP : 0)
                          | (d->watchdog ? RHI_WATCHDOG : 0) | (d->fault ? RHI_FAULT : 0));
    r.session = d->session;
    r.seq = d->seq;
    r.cmd_seq = d->have_cmd ? d->cmd_seq : RHI_NO_SEQ;
    r.n = d->cfg.n;
    r.k = d->k;
    r.t_dev = t_dev;
    memcpy(r.q, q, sizeof(double) * r.n);
    memcpy(r.dq, dq, sizeof(double) * r.n);
    if (r.k) memcpy(r.s, s, sizeof(double) * r.k);
    len = rhi_pack_reading(pkt, sizeof pkt, &r);
    d->seq++;
    d->stats.readings++;
    return sendto(d->sock, pkt, len, 0, (const struct sockaddr *)&d->client, sizeof d->client) == (ssize_t)len
        ? 0 : -1;
}

int rhi_device_torque(rhi_device *d, double now, double *tau) {
    size_t i;
    if (d->active && now - d->last_valid > d->cfg.session_timeout) end_session(d, "session timed out:");
    if (d->have_cmd && !d->watchdog && now - d->last_valid > d->cfg.watchdog) {
        d->watchdog = 1;
        d->stats.watchdog_trips++;
    }
    d->enabled = d->active && d->have_cmd && (d->cmd_flags & RHI_ENABLE) && !d->watchdog && !d->estop && !d->fault;
    for (i = 0; i < d->cfg.n; i++) {
        double t = d->tau_cmd[i];
        t = t < d->cfg.tau_min[i] ? d->cfg.tau_min[i] : t > d->cfg.tau_max[i] ? d->cfg.tau_max[i] : t;
        tau[i] = d->enabled ? t : 0.0;
    }
    return d->enabled;
}

void rhi_device_fault(rhi_device *d) { d->fault = 1; d->enabled = 0; }

void rhi_device_close(rhi_device *d) {
    if (d->sock >= 0) close(d->sock);
    d->sock = -1;
    d->active = 0;
}

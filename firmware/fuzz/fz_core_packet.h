/*
 * fz_core_packet.h - the one place that knows the core's decoded-packet struct:
 * converts an exo_packet (core/wire.h) into the model's fz_pkt so that the harnesses
 * compare fields by value.
 */
#ifndef FZ_CORE_PACKET_H
#define FZ_CORE_PACKET_H

#include "fz_wire_model.h"
#include "wire.h"

/* The core's verdict as a shared reason name and, when valid, its fields in `out`. */
const char *fz_core_decode(const exo_hmac_key *key, const uint8_t *d, size_t n, fz_pkt *out);

/* 0 if the fields a valid packet of `m->type` carries are equal, else the line of the
 * first difference (so a crash report names the field). */
int fz_pkt_diff(const fz_pkt *core, const fz_pkt *m);

#endif /* FZ_CORE_PACKET_H */

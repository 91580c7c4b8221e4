/*
 * phy.h - the on-board LAN8742A Ethernet PHY over MDIO (IEEE 802.3 clause 22
 * registers, plus the LAN8742A's special control/status register 31 for the
 * negotiated speed and duplex).
 */
#ifndef PHY_H
#define PHY_H

#include <stdint.h>

typedef struct {
    int up;      /* link established */
    int full;    /* full duplex */
    int fast;    /* 100 Mbit/s */
} phy_link;

/* Reset the PHY and start auto-negotiation. 0, or -1 if no PHY answers (wrong
 * identifier, MDIO timeout). Does not wait for the link. */
int phy_init(void);

/* The current link state (two MDIO reads, about 60 us). -1 on an MDIO timeout. */
int phy_poll(phy_link *out);

#endif /* PHY_H */

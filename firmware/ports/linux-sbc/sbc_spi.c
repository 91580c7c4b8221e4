/* sbc_spi.c - spidev ioctls for the AS5048A bus. */
#include "sbc_spi.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/spi/spidev.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include "sbc_spi_frames.h"

#define MAX_FRAMES 8

int sbc_spi_open(sbc_spi *s, const sbc_options *o, char *err, size_t errlen)
{
    memset(s, 0, sizeof *s);
    for (unsigned i = 0; i < SBC_MAX_SPIDEV; i++) {
        s->fd[i] = -1;
    }
    s->hz = o->spi_hz;
    s->word_bits = o->spi_word_bits;
    for (unsigned i = 0; i < o->n_spidev; i++) {
        const char *path = o->spidev[i];
        int fd = open(path, O_RDWR | O_CLOEXEC);
        if (fd < 0) {
            snprintf(err, errlen, "%s: %s", path, strerror(errno));
            sbc_spi_close(s);
            return -1;
        }
        s->fd[i] = fd;
        s->n = i + 1;
        uint8_t mode = SPI_MODE_1; /* CPOL 0, CPHA 1: the AS5048A's mode */
        uint8_t lsb = 0;
        uint8_t bits = (uint8_t)s->word_bits;
        uint32_t hz = s->hz;
        if (ioctl(fd, SPI_IOC_WR_MODE, &mode) < 0) {
            snprintf(err, errlen, "%s: cannot set SPI mode 1: %s", path, strerror(errno));
            sbc_spi_close(s);
            return -1;
        }
        if (ioctl(fd, SPI_IOC_WR_LSB_FIRST, &lsb) < 0) {
            snprintf(err, errlen, "%s: cannot set MSB first: %s", path, strerror(errno));
            sbc_spi_close(s);
            return -1;
        }
        if (ioctl(fd, SPI_IOC_WR_BITS_PER_WORD, &bits) < 0) {
            snprintf(err, errlen, "%s: %u-bit words refused (%s); try --spi-word 8", path,
                     s->word_bits, strerror(errno));
            sbc_spi_close(s);
            return -1;
        }
        if (ioctl(fd, SPI_IOC_WR_MAX_SPEED_HZ, &hz) < 0) {
            snprintf(err, errlen, "%s: cannot set %u Hz: %s", path, (unsigned)hz,
                     strerror(errno));
            sbc_spi_close(s);
            return -1;
        }
    }
    return 0;
}

int sbc_spi_transfer(sbc_spi *s, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    if (chip >= s->n || n == 0 || n > MAX_FRAMES) {
        return -1;
    }
    uint8_t txb[2 * MAX_FRAMES], rxb[2 * MAX_FRAMES];
    uint16_t txw[MAX_FRAMES], rxw[MAX_FRAMES];
    struct spi_ioc_transfer t;
    memset(&t, 0, sizeof t);
    t.len = (uint32_t)(2 * n);
    t.speed_hz = s->hz;
    t.bits_per_word = (uint8_t)s->word_bits;
    if (s->word_bits == 8) {
        sbc_frames_to_bytes(tx, n, txb);
        t.tx_buf = (uintptr_t)txb;
        t.rx_buf = (uintptr_t)rxb;
    } else {
        /* 16-bit words: spidev takes them in CPU byte order and shifts MSB first. */
        memcpy(txw, tx, 2 * n);
        t.tx_buf = (uintptr_t)txw;
        t.rx_buf = (uintptr_t)rxw;
    }
    /* One transfer per call: chip select stays asserted for all n frames and is
     * released at the end of the message, as the daisy chain needs. */
    if (ioctl(s->fd[chip], SPI_IOC_MESSAGE(1), &t) < 0) {
        return -1;
    }
    if (s->word_bits == 8) {
        sbc_bytes_to_frames(rxb, n, rx);
    } else {
        memcpy(rx, rxw, 2 * n);
    }
    return 0;
}

void sbc_spi_close(sbc_spi *s)
{
    for (unsigned i = 0; i < SBC_MAX_SPIDEV; i++) {
        if (s->fd[i] >= 0) {
            close(s->fd[i]);
            s->fd[i] = -1;
        }
    }
    s->n = 0;
}

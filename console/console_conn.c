/* kogei console: its connections, who may hold one and for how long (docs/console.md,
 * "Security"). The server (console_http.c) reports each connection's start, its
 * requests, answers and close; this file admits it, and a reaper thread closes it
 * when it overstays a deadline. Nothing here knows HTTP: a connection only waits for
 * a request, is handled, or is sent an answer.
 *
 * A connection is closed by shutting its socket down, which wakes the server's
 * thread for it; the server then closes it and reports the close. Its number is used
 * only while the connection is known open (conn_lock), so it never names another
 * file. */
#include <linux/tcp.h>
#include <netinet/in.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

#include "console.h"

/* The client's address as 16 bytes, an IPv4 one as ::ffff:a.b.c.d (so the two forms
 * of one client are one address). */
static void addr_key(const struct sockaddr *sa, unsigned char key[16])
{
	memset(key, 0, 16);
	if (sa && sa->sa_family == AF_INET6) {
		memcpy(key, &((const struct sockaddr_in6 *)sa)->sin6_addr, 16);
	} else if (sa && sa->sa_family == AF_INET) {
		key[10] = key[11] = 0xff;
		memcpy(key + 12, &((const struct sockaddr_in *)sa)->sin_addr, 4);
	}
}

/* Bytes sent on fd that the client's side has acknowledged (taken into its receive
 * buffer: they stop when it stops reading). Linux 4.1 and later. */
static int acked_bytes(int fd, uint64_t *out)
{
	struct tcp_info ti;
	socklen_t n = sizeof(ti);
	memset(&ti, 0, sizeof(ti));
	if (getsockopt(fd, IPPROTO_TCP, TCP_INFO, &ti, &n) ||
	    n < offsetof(struct tcp_info, tcpi_bytes_acked) + sizeof(ti.tcpi_bytes_acked))
		return -1;
	*out = ti.tcpi_bytes_acked;
	return 0;
}

/* An answer moves on when the client has taken CONSOLE_SEND_FLOOR more bytes of it:
 * its clock restarts. A client that stopped reading, or reads a trickle, does not. */
static void conn_progress(console_conn *k, double now)
{
	uint64_t acked;
	if (k->phase == CONSOLE_CONN_SEND && !acked_bytes(k->fd, &acked) &&
	    acked - k->acked >= CONSOLE_SEND_FLOOR) {
		k->acked = acked;
		k->since = now;
	}
}

static double conn_deadline(const console *c, const console_conn *k)
{
	return k->since + (k->phase == CONSOLE_CONN_SEND ? c->send_timeout : c->header_timeout);
}

/* Close a connection. An answer's unread rest is dropped with a reset: a FIN would
 * wait behind it, and the client would never see the connection end. */
static void conn_shut(console_conn *k)
{
	if (k->phase == CONSOLE_CONN_SEND) {
		struct linger abort_close = {1, 0};
		setsockopt(k->fd, SOL_SOCKET, SO_LINGER, &abort_close, sizeof(abort_close));
	}
	shutdown(k->fd, SHUT_RDWR);
	k->closing = 1;
}

/* The connection a newcomer replaces: of those waiting for a request or sending an
 * answer (not one being handled), from the address `key` (NULL: any), the one that
 * has waited, or not moved its answer on, the longest. NULL when all are handled. */
static console_conn *stalest(console *c, const unsigned char *key, double now)
{
	console_conn *best = NULL;
	for (size_t i = 0; i < CONSOLE_CONN_SLOTS; i++) {
		console_conn *k = &c->conns[i];
		if (!k->used || k->closing || k->phase == CONSOLE_CONN_HANDLE ||
		    (key && memcmp(k->addr, key, sizeof(k->addr))))
			continue;
		conn_progress(k, now);
		if (!best || k->since < best->since)
			best = k;
	}
	return best;
}

console_conn *console_conn_admit(console *c, int fd, const struct sockaddr *client)
{
	unsigned char key[16];
	addr_key(client, key);
	pthread_mutex_lock(&c->conn_lock);
	double now = console_now();
	size_t n_addr = 0, n_all = 0;
	console_conn *slot = NULL;
	for (size_t i = 0; i < CONSOLE_CONN_SLOTS; i++) {
		console_conn *k = &c->conns[i];
		if (!k->used && !slot)
			slot = k;
		if (!k->used || k->closing)
			continue;
		n_all++;
		n_addr += !memcmp(k->addr, key, sizeof(key));
	}
	int addr_full = n_addr >= CONSOLE_PER_CLIENT_MAX;
	int full = addr_full || n_all >= CONSOLE_CONNECTIONS_MAX;
	console_conn *victim = full ? stalest(c, addr_full ? key : NULL, now) : NULL;
	if (!slot || (full && !victim)) {
		shutdown(fd, SHUT_RDWR);
		c->conns_refused++;
		slot = NULL;
	} else {
		if (victim) {
			conn_shut(victim);
			c->conns_evicted++;
		}
		memset(slot, 0, sizeof(*slot));
		slot->used = 1;
		slot->fd = fd;
		memcpy(slot->addr, key, sizeof(key));
		slot->phase = CONSOLE_CONN_WAIT;
		slot->since = now;
	}
	pthread_mutex_unlock(&c->conn_lock);
	return slot;
}

void console_conn_release(console *c, console_conn *k)
{
	pthread_mutex_lock(&c->conn_lock);
	k->used = 0;
	pthread_mutex_unlock(&c->conn_lock);
}

int console_conn_begin(console *c, console_conn *k)
{
	int ok = 0;
	pthread_mutex_lock(&c->conn_lock);
	if (k && !k->closing) {
		k->phase = CONSOLE_CONN_HANDLE;
		ok = 1;
	}
	pthread_mutex_unlock(&c->conn_lock);
	return ok;
}

void console_conn_end(console *c, console_conn *k, int answered)
{
	pthread_mutex_lock(&c->conn_lock);
	if (answered) {
		k->phase = CONSOLE_CONN_SEND;
		k->since = console_now();
		if (acked_bytes(k->fd, &k->acked))
			k->acked = 0;
	} else {
		k->phase = CONSOLE_CONN_WAIT; /* its request's clock runs on */
	}
	pthread_mutex_unlock(&c->conn_lock);
}

void console_conn_answered(console *c, console_conn *k)
{
	pthread_mutex_lock(&c->conn_lock);
	k->phase = CONSOLE_CONN_WAIT;
	k->since = console_now();
	pthread_mutex_unlock(&c->conn_lock);
}

static void *reaper_main(void *arg)
{
	console *c = arg;
	pthread_mutex_lock(&c->conn_lock);
	while (!c->conn_stop) {
		double now = console_now();
		for (size_t i = 0; i < CONSOLE_CONN_SLOTS; i++) {
			console_conn *k = &c->conns[i];
			if (!k->used || k->closing || k->phase == CONSOLE_CONN_HANDLE)
				continue;
			conn_progress(k, now);
			if (now < conn_deadline(c, k))
				continue;
			if (k->phase == CONSOLE_CONN_SEND)
				c->conns_send_timed_out++;
			else
				c->conns_timed_out++;
			conn_shut(k);
		}
		pthread_mutex_unlock(&c->conn_lock);
		nanosleep(&(struct timespec){0, 50000000L}, NULL);
		pthread_mutex_lock(&c->conn_lock);
	}
	pthread_mutex_unlock(&c->conn_lock);
	return NULL;
}

int console_conn_start(console *c)
{
	return pthread_create(&c->reaper_thread, NULL, reaper_main, c) ? -1 : 0;
}

void console_conn_stop(console *c)
{
	pthread_mutex_lock(&c->conn_lock);
	c->conn_stop = 1;
	pthread_mutex_unlock(&c->conn_lock);
	pthread_join(c->reaper_thread, NULL);
	if (c->conns_timed_out)
		fprintf(stderr, "kogei console: %ld connection(s) closed at the request deadline "
		        "(--header-timeout %g s)\n", c->conns_timed_out, c->header_timeout);
	if (c->conns_send_timed_out)
		fprintf(stderr, "kogei console: %ld answer(s) cut off at the send deadline "
		        "(--send-timeout %g s: less than %d KiB taken in that time)\n",
		        c->conns_send_timed_out, c->send_timeout, CONSOLE_SEND_FLOOR / 1024);
	if (c->conns_evicted || c->conns_refused)
		fprintf(stderr, "kogei console: %ld waiting or stalled connection(s) closed for "
		        "newer ones, %ld refused (%d busy from one address, or %d in all)\n",
		        c->conns_evicted, c->conns_refused, CONSOLE_PER_CLIENT_MAX,
		        CONSOLE_CONNECTIONS_MAX);
}

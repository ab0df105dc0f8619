//! The accept loop: one thread per connection, at most
//! [`ServerConfig::max_connections`](super::ServerConfig::max_connections) at
//! once; when full, a connection still silent in its handshake makes room.

use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::Duration;

use super::session::handle_connection;
use super::{ACCEPT_TICK, Shared, lock};
use crate::ErrorCode;
use crate::protocol::{Reply, close_gracefully, write_line};

pub(super) fn accept_loop(listener: &TcpListener, shared: &Arc<Shared>) {
    let mut workers: Vec<JoinHandle<()>> = Vec::new();
    let mut next_id: u64 = 0;
    while !shared.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, peer)) => {
                workers.retain(|w| !w.is_finished());
                if shared.connections.load(Ordering::SeqCst) >= shared.config.max_connections
                    && !evict_one_pending(shared)
                {
                    shared.log(peer, "refused: too many connections");
                    refuse_now(stream);
                    continue;
                }
                next_id += 1;
                let id = next_id;
                if let Ok(handle) = stream.try_clone() {
                    lock(&shared.pending).push((id, peer, handle));
                }
                // Released when the thread ends, however it ends (also by a panic).
                let slot = Slot {
                    shared: Arc::clone(shared),
                    id,
                };
                shared.connections.fetch_add(1, Ordering::SeqCst);
                let spawned = std::thread::Builder::new()
                    .name("voxoct-tt-conn".into())
                    .spawn(move || {
                        handle_connection(stream, peer, &slot.shared, id);
                        drop(slot);
                    });
                if let Ok(h) = spawned {
                    workers.push(h);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(ACCEPT_TICK);
            }
            // Transient accept errors (aborted connection, out of file
            // descriptors): back off and keep serving.
            Err(_) => std::thread::sleep(ACCEPT_TICK * 5),
        }
    }
    for w in workers {
        let _ = w.join();
    }
}

/// A connection's place in the count, given back on drop.
struct Slot {
    shared: Arc<Shared>,
    id: u64,
}

impl Drop for Slot {
    fn drop(&mut self) {
        lock(&self.shared.pending).retain(|(id, _, _)| *id != self.id);
        self.shared.connections.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Closes the oldest connection still in its handshake, from the address
/// with the most such connections; `false` when there is none.
fn evict_one_pending(shared: &Shared) -> bool {
    let mut pending = lock(&shared.pending);
    let count = |ip: std::net::IpAddr| pending.iter().filter(|(_, p, _)| p.ip() == ip).count();
    let Some(ip) = pending
        .iter()
        .map(|(_, p, _)| p.ip())
        .max_by_key(|&ip| count(ip))
    else {
        return false;
    };
    let Some(i) = pending.iter().position(|(_, p, _)| p.ip() == ip) else {
        return false;
    };
    let (_, peer, stream) = pending.remove(i);
    shared.log(peer, "evicted: still no handshake and the server is full");
    let _ = stream.shutdown(std::net::Shutdown::Both);
    true
}

fn refuse_now(mut stream: TcpStream) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_write_timeout(Some(Duration::from_millis(100)));
    let reply = Reply::Err {
        code: ErrorCode::Busy,
        message: "too many connections; try again later".into(),
    };
    let _ = write_line(&mut stream, &reply.to_line());
    close_gracefully(&mut stream, Duration::from_millis(20));
}

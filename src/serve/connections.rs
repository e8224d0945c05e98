//! A cap on the gRPC plane's open connections: each connection may hold up
//! to a connection window of unread stream data (see `grpc_server`) and a
//! file descriptor, so their number bounds the server's memory and
//! descriptors.
//!
//! A connection past the cap is told so: up to [`REFUSALS`] of them at a
//! time are served for [`REFUSAL_GRACE`], every call on them answered
//! RESOURCE_EXHAUSTED with the cap named (the interceptor asks
//! [`Connections::refused`]), and then closed. Past those too, a
//! connection is closed at once (the client's call then fails with a
//! transport error, or tonic's channel waits). Either way it is counted as
//! rejected, reason `connection_cap`, once a connection. The refused ones
//! are not in the open count.

use std::collections::HashSet;
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tonic::transport::server::{Connected, TcpConnectInfo};

/// Connections past the cap served at once to be told so: each may hold a
/// connection window of unread data for [`REFUSAL_GRACE`], so their
/// number is small whatever the cap.
pub const REFUSALS: usize = 8;

/// How long a refused connection is served (its calls answered
/// RESOURCE_EXHAUSTED) before the server closes it.
pub const REFUSAL_GRACE: Duration = Duration::from_secs(5);

/// The open connections, at most `max`, and those past the cap being
/// refused.
pub struct Connections {
    permits: Arc<Semaphore>,
    refusals: Arc<Semaphore>,
    /// The peers of the refused connections (a peer address is unique
    /// among open TCP connections).
    refused: Arc<Mutex<HashSet<SocketAddr>>>,
    max: usize,
}

/// What [`Connections::admit`] made of a connection.
pub enum Admission {
    /// Counted as open while it lives.
    Open(Counted),
    /// Past the cap: served for [`REFUSAL_GRACE`], its calls refused.
    Refused(Counted),
    /// Past the cap with every refusal slot taken: to be dropped.
    Dropped,
}

impl Connections {
    pub fn new(max: usize) -> Connections {
        Connections {
            permits: Arc::new(Semaphore::new(max)),
            refusals: Arc::new(Semaphore::new(REFUSALS)),
            refused: Arc::default(),
            max,
        }
    }

    /// `s` counted as open until dropped; past `max` open, refused (see
    /// the module documentation) or dropped.
    pub fn admit(&self, s: TcpStream) -> Admission {
        if let Ok(permit) = self.permits.clone().try_acquire_owned() {
            return Admission::Open(Counted {
                io: s,
                _permit: permit,
                refusal: None,
            });
        }
        let (Ok(permit), Ok(peer)) = (self.refusals.clone().try_acquire_owned(), s.peer_addr())
        else {
            return Admission::Dropped;
        };
        peers(&self.refused).insert(peer);
        Admission::Refused(Counted {
            io: s,
            _permit: permit,
            refusal: Some(Refusal {
                peer,
                set: self.refused.clone(),
                close: Box::pin(tokio::time::sleep(REFUSAL_GRACE)),
            }),
        })
    }

    /// Whether the connection from `peer` is one past the cap. Without a
    /// lock while none is (every call asks): a refused connection holds
    /// its refusal permit from before it is served until it goes.
    pub fn refused(&self, peer: SocketAddr) -> bool {
        self.refusals.available_permits() < REFUSALS && peers(&self.refused).contains(&peer)
    }

    /// The cap.
    pub fn max(&self) -> usize {
        self.max
    }

    /// Connections open now.
    pub fn open(&self) -> usize {
        self.max - self.permits.available_permits()
    }
}

/// A connection that counts as open (or as refused) while it lives.
pub struct Counted {
    io: TcpStream,
    _permit: OwnedSemaphorePermit,
    refusal: Option<Refusal>,
}

/// What a refused connection keeps: its entry in the refused set, taken
/// out when it goes, and when it closes.
struct Refusal {
    peer: SocketAddr,
    set: Arc<Mutex<HashSet<SocketAddr>>>,
    close: Pin<Box<tokio::time::Sleep>>,
}

impl Drop for Refusal {
    fn drop(&mut self) {
        peers(&self.set).remove(&self.peer);
    }
}

/// The refused peers, locked; the set stays whole whatever panicked while
/// it was held.
fn peers(set: &Mutex<HashSet<SocketAddr>>) -> MutexGuard<'_, HashSet<SocketAddr>> {
    set.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Counted {
    /// Whether a refused connection's grace is over (registering the
    /// waker for its end otherwise): it then reads as closed by the peer
    /// and writes fail, and the server drops it.
    fn closed(&mut self, cx: &mut Context<'_>) -> bool {
        self.refusal
            .as_mut()
            .is_some_and(|r| r.close.as_mut().poll(cx).is_ready())
    }
}

impl Connected for Counted {
    type ConnectInfo = TcpConnectInfo;
    fn connect_info(&self) -> TcpConnectInfo {
        self.io.connect_info()
    }
}

impl AsyncRead for Counted {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        if self.closed(cx) {
            return Poll::Ready(Ok(()));
        }
        Pin::new(&mut self.io).poll_read(cx, buf)
    }
}

impl AsyncWrite for Counted {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        if self.closed(cx) {
            return Poll::Ready(Err(io::ErrorKind::BrokenPipe.into()));
        }
        Pin::new(&mut self.io).poll_write(cx, buf)
    }
    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        if self.closed(cx) {
            return Poll::Ready(Err(io::ErrorKind::BrokenPipe.into()));
        }
        Pin::new(&mut self.io).poll_write_vectored(cx, bufs)
    }
    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }
    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_flush(cx)
    }
    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_shutdown(cx)
    }
}

//! The frame thread: ethercrab's PDU loop over a raw socket of our own.
//!
//! ethercrab's own `std::tx_rx_task` ends on the first frame it cannot match to a PDU in
//! flight, such as a response that comes back after its PDU timed out. After that, every
//! later exchange times out and the bus is gone for good. One late frame (a subdevice or
//! a busy host stalled for longer than the frame timeout) then became a permanent
//! FIELDBUS_LOST, even though the watchdog would have tolerated it. This loop counts such a
//! frame, drops it and carries on. A real loss still ends in FIELDBUS_LOST, through the
//! backend's watchdog.

use async_io::{Async, IoSafe};
use core::{
    future::Future,
    pin::Pin,
    task::{Context, Poll},
};
use ethercrab::{error::Error, PduRx, PduTx};
use futures_lite::{AsyncRead, AsyncWrite};
use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, RawFd};
use std::sync::atomic::{AtomicU64, Ordering};

/// Frames received that matched no PDU in flight (late or corrupted), and sends that failed.
pub static STRAY_FRAMES: AtomicU64 = AtomicU64::new(0);
pub static SEND_ERRORS: AtomicU64 = AtomicU64::new(0);

const ETHERCAT_ETHERTYPE: u16 = 0x88A4;
/// An EtherCAT frame is at most a full Ethernet frame (1514 bytes without FCS).
const FRAME_BUF: usize = 2048;

/// An AF_PACKET socket bound to one interface, receiving and sending EtherType 0x88A4 only.
pub struct RawSocket {
    fd: RawFd,
}

impl RawSocket {
    pub fn open(ifname: &str) -> io::Result<Self> {
        let name = std::ffi::CString::new(ifname)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface name contains NUL"))?;
        let protocol = i32::from(ETHERCAT_ETHERTYPE.to_be());
        // SAFETY: plain socket(2); the descriptor is owned by the value returned.
        let fd = unsafe { libc::socket(libc::AF_PACKET, libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC, protocol) };
        if fd < 0 {
            return Err(io::Error::last_os_error());
        }
        let socket = RawSocket { fd };
        // SAFETY: `name` is NUL-terminated.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: sockaddr_ll is plain data; all-zero is a valid value.
        let mut addr: libc::sockaddr_ll = unsafe { core::mem::zeroed() };
        addr.sll_family = libc::AF_PACKET as u16;
        addr.sll_protocol = ETHERCAT_ETHERTYPE.to_be();
        addr.sll_ifindex = index as i32;
        // SAFETY: `addr` is a valid sockaddr_ll of the length given.
        let rc = unsafe {
            libc::bind(
                fd,
                (&addr as *const libc::sockaddr_ll).cast::<libc::sockaddr>(),
                core::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if rc != 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(socket)
    }
}

impl Drop for RawSocket {
    fn drop(&mut self) {
        // SAFETY: the descriptor is ours and closed once.
        unsafe { libc::close(self.fd) };
    }
}

impl AsRawFd for RawSocket {
    fn as_raw_fd(&self) -> RawFd {
        self.fd
    }
}

impl AsFd for RawSocket {
    fn as_fd(&self) -> BorrowedFd<'_> {
        // SAFETY: the descriptor lives as long as `self`.
        unsafe { BorrowedFd::borrow_raw(self.fd) }
    }
}

// SAFETY: Read and Write below never close or replace the descriptor.
unsafe impl IoSafe for RawSocket {}

impl io::Read for RawSocket {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // SAFETY: `buf` is writable for its length.
        let n = unsafe { libc::recv(self.fd, buf.as_mut_ptr().cast(), buf.len(), 0) };
        if n < 0 {
            Err(io::Error::last_os_error())
        } else {
            Ok(n as usize)
        }
    }
}

impl io::Write for RawSocket {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        // SAFETY: `buf` is readable for its length.
        let n = unsafe { libc::send(self.fd, buf.as_ptr().cast(), buf.len(), 0) };
        if n < 0 {
            Err(io::Error::last_os_error())
        } else {
            Ok(n as usize)
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Sends every frame the PDU loop has ready and hands every frame received to it, for as
/// long as the master lives. Never ends on a bad frame.
pub struct TxRx<'a> {
    socket: Async<RawSocket>,
    tx: PduTx<'a>,
    rx: PduRx<'a>,
    buf: [u8; FRAME_BUF],
}

impl<'a> TxRx<'a> {
    pub fn new(ifname: &str, tx: PduTx<'a>, rx: PduRx<'a>) -> io::Result<Self> {
        Ok(TxRx { socket: Async::new(RawSocket::open(ifname)?)?, tx, rx, buf: [0; FRAME_BUF] })
    }
}

impl Future for TxRx<'_> {
    type Output = ();

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let this = &mut *self;
        this.tx.replace_waker(cx.waker());
        if this.tx.should_exit() {
            return Poll::Ready(());
        }
        while let Some(frame) = this.tx.next_sendable_frame() {
            let socket = &mut this.socket;
            let sent = frame.send_blocking(|data| match Pin::new(&mut *socket).poll_write(cx, data) {
                Poll::Ready(Ok(n)) => Ok(n),
                Poll::Ready(Err(_)) => Err(Error::SendFrame),
                Poll::Pending => Ok(0), // not sent: the frame stays sendable, we are woken when writable
            });
            if sent.is_err() {
                // A link down refuses the send; the frame's PDU times out and the backend's
                // watchdog decides. Try again on the next wake, not in a busy loop.
                SEND_ERRORS.fetch_add(1, Ordering::Relaxed);
                break;
            }
        }
        loop {
            match Pin::new(&mut this.socket).poll_read(cx, &mut this.buf) {
                Poll::Ready(Ok(n)) => {
                    if this.rx.receive_frame(&this.buf[..n]).is_err() {
                        STRAY_FRAMES.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Poll::Ready(Err(e)) if e.kind() == io::ErrorKind::Interrupted => {}
                // A socket error (the link went down): woken again by the next frame to send.
                Poll::Ready(Err(_)) => break,
                Poll::Pending => break,
            }
        }
        Poll::Pending
    }
}

//! The frame thread: ethercrab's PDU loop over a raw socket of our own, on a plain
//! SCHED_FIFO thread that waits in poll(2) on the socket and an eventfd, and nothing else.
//!
//! Why not an async executor: with async-io's `block_on`, a thread that has waited on the
//! reactor for more than 500 us without a notification of its own hands the reactor to
//! async-io's helper thread, an ordinary (SCHED_OTHER) thread, and parks. Every cycle the
//! real-time loop registers a PDU timer, which notifies the reactor, so between two cycles
//! this hand-over happened every time: the answer to the next frame was then noticed by the
//! helper thread, which on a loaded host waited milliseconds for a CPU behind ordinary
//! work. Those were the stale cycles under load (issue 22). Here, the wake-up chain of an
//! exchange is real-time threads only: the cycle stages a frame and writes the eventfd; this
//! thread sends it, is woken by the answer, hands it to the PDU loop, which unparks the
//! cycle (a futex).
//!
//! ethercrab's own `std::tx_rx_task` also ends on the first frame it cannot match to a PDU
//! in flight, such as a response that comes back after its PDU timed out; every later
//! exchange then timed out, a permanent FIELDBUS_LOST after one late frame. This loop counts
//! such a frame, drops it and carries on. A real loss still ends in FIELDBUS_LOST, through
//! the backend's stale-cycle count.

use core::task::Waker;
use ethercrab::{error::Error, PduRx, PduTx};
use std::io;
use std::os::fd::RawFd;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Frames received that matched no PDU in flight (late or corrupted), and sends that failed.
pub static STRAY_FRAMES: AtomicU64 = AtomicU64::new(0);
pub static SEND_ERRORS: AtomicU64 = AtomicU64::new(0);

const ETHERCAT_ETHERTYPE: u16 = 0x88A4;
/// An EtherCAT frame is at most a full Ethernet frame (1514 bytes without FCS).
const FRAME_BUF: usize = 2048;
/// After a send the kernel refused (link down), the next attempt: not a busy loop.
const RETRY_MS: i32 = 1;

fn last_error() -> io::Error {
    io::Error::last_os_error()
}

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
            return Err(last_error());
        }
        let socket = RawSocket { fd };
        // SAFETY: `name` is NUL-terminated.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(last_error());
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
            return Err(last_error());
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

/// The PDU loop's "a frame is ready to send" signal: an eventfd this thread polls.
struct EventFd(RawFd);

impl std::task::Wake for EventFd {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        let one: u64 = 1;
        // SAFETY: writes 8 bytes from a live u64 to our eventfd (never closed: the master
        // lives as long as the process). A full counter (EAGAIN) is already a wake-up.
        unsafe { libc::write(self.0, (&one as *const u64).cast(), 8) };
    }
}

/// The socket and the two halves of ethercrab's PDU loop, behind one mutex: the frame
/// thread drives them, and so does the real-time cycle for its own exchange (it sends its
/// frame and sleeps on the socket itself: lib.rs `run_until`).
pub struct TxRx<'a> {
    socket: RawSocket,
    wake_fd: RawFd,
    /// Wakes the frame thread (the eventfd): the PDU loop's waker while the thread drives it.
    pub waker: Waker,
    pub tx: PduTx<'a>,
    rx: PduRx<'a>,
    buf: [u8; FRAME_BUF],
}

impl<'a> TxRx<'a> {
    pub fn new(ifname: &str, tx: PduTx<'a>, rx: PduRx<'a>) -> io::Result<Self> {
        let socket = RawSocket::open(ifname)?;
        // SAFETY: plain eventfd(2).
        let wake_fd = unsafe { libc::eventfd(0, libc::EFD_NONBLOCK | libc::EFD_CLOEXEC) };
        if wake_fd < 0 {
            return Err(last_error());
        }
        let waker = Waker::from(Arc::new(EventFd(wake_fd)));
        Ok(TxRx { socket, wake_fd, waker, tx, rx, buf: [0; FRAME_BUF] })
    }

    /// Sends every frame ready; false when the kernel refused one (link down: the frame
    /// stays sendable, and the exchange waiting for it becomes stale at its deadline).
    pub fn send_all(&mut self) -> bool {
        let fd = self.socket.fd;
        while let Some(frame) = self.tx.next_sendable_frame() {
            let sent = frame.send_blocking(|data| {
                // SAFETY: `data` is readable for its length.
                let n = unsafe { libc::send(fd, data.as_ptr().cast(), data.len(), 0) };
                if n < 0 {
                    Err(Error::SendFrame)
                } else {
                    Ok(n as usize)
                }
            });
            if sent.is_err() {
                SEND_ERRORS.fetch_add(1, Ordering::Relaxed);
                return false;
            }
        }
        true
    }

    /// Hands every frame waiting in the socket to the PDU loop (which wakes its exchange).
    pub fn receive_all(&mut self) {
        loop {
            // SAFETY: `buf` is writable for its length.
            let n = unsafe { libc::recv(self.socket.fd, self.buf.as_mut_ptr().cast(), self.buf.len(), libc::MSG_DONTWAIT) };
            if n < 0 {
                if last_error().kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return; // nothing more (EAGAIN), or the link went down (read once, cleared)
            }
            if self.rx.receive_frame(&self.buf[..n as usize]).is_err() {
                STRAY_FRAMES.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Sleeps until a frame can be read from the socket or `timeout` passes (ppoll(2): no
    /// millisecond rounding).
    pub fn wait_readable(&self, timeout: std::time::Duration) {
        let ts = libc::timespec { tv_sec: timeout.as_secs() as libc::time_t, tv_nsec: timeout.subsec_nanos() as libc::c_long };
        let mut fds = [libc::pollfd { fd: self.socket.fd, events: libc::POLLIN, revents: 0 }];
        // SAFETY: one valid pollfd entry and a valid timespec; no signal mask change.
        unsafe { libc::ppoll(fds.as_mut_ptr(), 1, &ts, core::ptr::null()) };
    }

    /// Wakes the frame thread (after the cycle drove the loop itself and gives it back).
    pub fn kick(&self) {
        self.waker.wake_by_ref();
    }
}

/// The loop of the frame thread (never returns while the master lives). It holds the mutex
/// only while it sends and receives, never while it waits.
pub fn run(io: Arc<Mutex<TxRx<'static>>>) {
    let (fd, wake_fd) = {
        let g = io.lock().unwrap_or_else(|e| e.into_inner());
        (g.socket.fd, g.wake_fd)
    };
    loop {
        let sent = {
            let mut g = io.lock().unwrap_or_else(|e| e.into_inner());
            let t = &mut *g;
            // Registered before looking for frames: one staged after the look wakes the poll.
            t.tx.replace_waker(&t.waker);
            if t.tx.should_exit() {
                return;
            }
            let sent = t.send_all();
            t.receive_all();
            sent
        };
        let mut fds = [
            libc::pollfd { fd, events: libc::POLLIN, revents: 0 },
            libc::pollfd { fd: wake_fd, events: libc::POLLIN, revents: 0 },
        ];
        // SAFETY: two valid pollfd entries.
        unsafe { libc::poll(fds.as_mut_ptr(), 2, if sent { -1 } else { RETRY_MS }) };
        if fds[1].revents & libc::POLLIN != 0 {
            let mut count: u64 = 0;
            // SAFETY: reads 8 bytes into a live u64 (resets the eventfd's counter).
            unsafe { libc::read(wake_fd, (&mut count as *mut u64).cast(), 8) };
        }
    }
}

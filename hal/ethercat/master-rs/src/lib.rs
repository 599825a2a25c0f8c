//! SafeState's EtherCAT master: ethercrab (MIT/Apache-2.0) behind a plain C ABI, for the
//! `ethercat` backend of hal/. One master per process (ethercrab's PDU storage is static).
//!
//! Open and scan allocate and may take seconds (they run in BOOT); the cyclic exchange does
//! not allocate (after a thread's first) and waits only for the frame round trip, bounded by
//! its deadline, woken by the frame thread (txrx.rs): real-time threads only, no executor.

mod txrx;

use core::ffi::{c_char, CStr};
use ethercrab::{
    std::ethercat_now,
    error::{Error as EcError, MailboxError},
    subdevice_group::{DcConfiguration, HasDc, Op, PreOp, SafeOp},
    Command, DcSync, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress, RetryBehaviour, SubDeviceGroup,
    SubDeviceState, Timeouts,
};
use core::future::Future;
use core::pin::pin;
use core::task::{Context, Poll, Waker};
use futures_lite::future::block_on;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const MAX_SUBDEVICES: usize = 16;
const MAX_PDI: usize = 1024;
const MAX_FRAMES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);

static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();
static OPENED: AtomicBool = AtomicBool::new(false);

/// One subdevice as found on the bus (C layout).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct SsEcatSub {
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub serial: u32,
    pub configured_address: u16,
    pub in_bytes: u16,
    pub out_bytes: u16,
    pub name: [c_char; 64],
}

/// The outcome of one cyclic exchange (C layout).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct SsEcatCycle {
    pub wkc: u16,
    pub expected_wkc: u16,
    pub count: u16,
    /// AL state per subdevice (1 INIT, 2 PREOP, 4 SAFEOP, 8 OP, 0 unknown).
    pub al_state: [u8; MAX_SUBDEVICES],
    /// With distributed clocks: the DC system time (ns) at which this frame's FRMW passed
    /// the reference clock (0 without DC).
    pub dc_time: u64,
}

type PreOpGroup = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, PreOp>;
type SafeGroup = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, SafeOp>;
type OpGroup = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, Op>;
type SafeGroupDc = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, SafeOp, HasDc>;
type OpGroupDc = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, Op, HasDc>;

/// The group once mapped: free-running, or with distributed clocks (SYNC0 configured on the
/// subdevices that asked for it, the reference clock's time carried by every exchange).
enum Safe {
    Free(SafeGroup),
    Dc(SafeGroupDc),
}
enum Running {
    Free(OpGroup),
    Dc(OpGroupDc),
}

/// The AL state codes of one exchange (see `SsEcatCycle::al_state`) and how many there are.
type AlStates = ([u8; MAX_SUBDEVICES], u16);

/// The same code on either kind of group (their types differ by the DC typestate).
macro_rules! on_group {
    ($e:expr, $Enum:ident, $g:ident => $body:expr) => {
        match $e {
            $Enum::Free($g) => $body,
            $Enum::Dc($g) => $body,
        }
    };
}

/// How long after the SYNC configuration the first SYNC0 pulse comes (ethercrab rounds it to
/// a whole number of cycles): room for the SAFE-OP transition and the watchdog writes before
/// OP, which the DC drives enter at their first pulse.
const DC_START_DELAY: Duration = Duration::from_millis(100);

/// FRMW frames of the reference clock's time sent at start-up, before SYNC0 is configured
/// (ethercrab's static drift compensation; ETG.1020 suggests ~15000, ethercrab 10000): the
/// clocks' loops settle there and are kept in step by the FRMW of every exchange after.
const DC_STATIC_SYNC_FRAMES: u32 = 3000;

pub struct SsEcatMaster {
    md: &'static MainDevice<'static>,
    preop: Option<PreOpGroup>,
    safe: Option<Safe>,
    op: Option<Running>,
    expected_wkc: u16,
    pdu_timeout: Duration,
    io: Arc<Mutex<txrx::TxRx<'static>>>,
    /// Each subdevice's configured station address, in bus order (set by the scan), and how many.
    addresses: [u16; MAX_SUBDEVICES],
    n_addresses: usize,
    error: [u8; 256],
}

impl SsEcatMaster {
    fn address(&self, position: u16) -> Option<u16> {
        let p = usize::from(position);
        (p < self.n_addresses).then(|| self.addresses[p])
    }

    fn fail(&mut self, msg: &str) -> i32 {
        let n = msg.len().min(self.error.len() - 1);
        self.error[..n].copy_from_slice(&msg.as_bytes()[..n]);
        self.error[n] = 0;
        -1
    }
}

fn state_code(s: SubDeviceState) -> u8 {
    match s {
        SubDeviceState::Init => 1,
        SubDeviceState::PreOp => 2,
        SubDeviceState::Bootstrap => 3,
        SubDeviceState::SafeOp => 4,
        SubDeviceState::Op => 8,
        _ => 0,
    }
}

fn write_err(err: *mut c_char, errlen: usize, msg: &str) {
    if err.is_null() || errlen == 0 {
        return;
    }
    let n = msg.len().min(errlen - 1);
    // SAFETY: the caller gives a buffer of errlen bytes.
    unsafe {
        core::ptr::copy_nonoverlapping(msg.as_ptr(), err as *mut u8, n);
        *err.add(n) = 0;
    }
}

/// The frame thread answers within the cycle only if it is not queued behind ordinary
/// work: SCHED_FIFO when permitted (as the real-time loop of `safestate run`), else a
/// warning on stderr and ordinary scheduling.
fn realtime(priority: i32) {
    if priority <= 0 {
        return;
    }
    let param = libc::sched_param { sched_priority: priority };
    // SAFETY: plain libc call on the current thread with a valid parameter.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc != 0 {
        eprintln!(
            "safestate: warning: EtherCAT frame thread: SCHED_FIFO not permitted ({}), running with normal \
             scheduling: on a busy host frames may come back late (stale cycles)",
            std::io::Error::from_raw_os_error(rc)
        );
    }
}

/// Wakes the thread that waits in `run_until` (std's park/unpark: a futex).
struct ThreadWaker(std::thread::Thread);

impl std::task::Wake for ThreadWaker {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.0.unpark();
    }
}

thread_local! {
    // One per thread that exchanges (the real-time loop, the keep-alive): allocated at its
    // first exchange, never after.
    static WAKER: Waker = Waker::from(Arc::new(ThreadWaker(std::thread::current())));
}

/// Polls `fut` on this thread until it is ready (Some) or `deadline` passes (None, the
/// future dropped by the caller).
///
/// With `io` (the real-time cycle's exchanges) this thread drives the socket itself: it sends
/// the frame its future staged and sleeps in ppoll(2) on the socket until the answer or the
/// deadline. The exchange then needs one wake-up on our side (this thread's, by the answer)
/// instead of three (the frame thread's to send, its own by the answer, then this thread's).
/// Each wake-up of a real-time thread can wait for an ordinary process to reach a preemption
/// point on a kernel that does not preempt kernel code (Linux's `preempt=none`, the default of
/// this CI VM's kernel): measured on the 2-core VM, 29 wake-ups of the frame thread delayed
/// by more than 0.3 ms in 10 s, up to 3.7 ms behind pip, with the other core idle. The frame
/// thread is kept out meanwhile (the mutex is held, the PDU loop's waker is a no-op).
/// Spinning instead of sleeping was tried: no better in 8-s runs under load, and on 2 cores
/// it takes the core the emulator's answer needs.
///
/// Without `io` (the start-up's keep-alive), the thread parks with a timeout, woken by the frame thread when an answer came back. No executor, no
/// reactor, and no ordinary thread on the path in either case (futures_lite's and
/// async-io's `block_on` fall back on async-io's helper thread; see txrx.rs).
/// The last part of a driven exchange's wait is spent awake (polling the socket) instead of
/// asleep: a thread that sleeps to its deadline wakes late from it when its CPU went idle
/// (a hypervisor wakes an idle vCPU in up to ~1 ms here) or runs an ordinary process in
/// kernel code, and the cycle overran its period in the stale cycles before a lockout.
/// Answers take ~0.1 ms; one that comes this late is stale anyway.
const SPIN_TAIL: Duration = Duration::from_micros(200);

fn run_until<F: Future>(fut: F, deadline: Instant, io: Option<&Mutex<txrx::TxRx<'static>>>) -> Option<F::Output> {
    WAKER.with(|waker| {
        let mut cx = Context::from_waker(waker);
        let mut fut = pin!(fut);
        // lock(), not try_lock(): the frame thread holds the loop only while it sends and
        // receives (microseconds, at a higher priority than the cycle's), and falling back to
        // waiting for it when it held the loop at that moment (it is woken by every answer
        // too, and a late wake-up made it take the loop just as the next exchange began)
        // put its wake-ups back on the path: sporadic stale cycles.
        if let Some(mut g) = io.map(|m| m.lock().unwrap_or_else(|e| e.into_inner())) {
            let t = &mut *g;
            t.tx.replace_waker(Waker::noop()); // staging our frame wakes nobody: sent below
            let mut done = None;
            loop {
                if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                    done = Some(v);
                    break;
                }
                t.send_all();
                t.receive_all();
                if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                    done = Some(v);
                    break;
                }
                let now = Instant::now();
                if now >= deadline {
                    break;
                }
                if deadline - now > SPIN_TAIL {
                    t.wait_readable(deadline - now - SPIN_TAIL);
                } else {
                    core::hint::spin_loop(); // the deadline itself is kept awake: see SPIN_TAIL
                }
            }
            t.tx.replace_waker(&t.waker);
            if done.is_none() {
                t.kick(); // anything left to send or receive is the frame thread's again
            }
            return done;
        }
        loop {
            if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                return Some(v);
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            std::thread::park_timeout(deadline - now); // spurious wake-ups: polled again
        }
    })
}

/// Opens the interface (raw socket, needs CAP_NET_RAW) and starts the frame thread.
/// `pdu_timeout_us` bounds every frame round trip. Returns null on failure (reason in `err`).
///
/// # Safety
/// `ifname` is a NUL-terminated string; `err` points to `errlen` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_open(
    ifname: *const c_char,
    pdu_timeout_us: u32,
    state_timeout_ms: u32,
    tx_rx_priority: i32,
    err: *mut c_char,
    errlen: usize,
) -> *mut SsEcatMaster {
    if ifname.is_null() {
        write_err(err, errlen, "no interface name");
        return core::ptr::null_mut();
    }
    let name = match CStr::from_ptr(ifname).to_str() {
        Ok(s) => s.to_owned(),
        Err(_) => {
            write_err(err, errlen, "interface name is not UTF-8");
            return core::ptr::null_mut();
        }
    };
    if OPENED.swap(true, Ordering::SeqCst) {
        write_err(err, errlen, "one EtherCAT master per process");
        return core::ptr::null_mut();
    }
    let Ok((tx, rx, pdu_loop)) = PDU_STORAGE.try_split() else {
        write_err(err, errlen, "PDU storage already in use");
        return core::ptr::null_mut();
    };
    let io = match txrx::TxRx::new(&name, tx, rx) {
        Ok(t) => Arc::new(Mutex::new(t)),
        Err(e) => {
            write_err(err, errlen, &format!("cannot open {}: {} (needs CAP_NET_RAW)", name, e));
            return core::ptr::null_mut();
        }
    };
    let thread_io = Arc::clone(&io);
    let spawned = std::thread::Builder::new().name("ecat-txrx".into()).spawn(move || {
        realtime(tx_rx_priority);
        txrx::run(thread_io);
    });
    if spawned.is_err() {
        write_err(err, errlen, "cannot start the frame thread");
        return core::ptr::null_mut();
    }
    let pdu_timeout = Duration::from_micros(u64::from(pdu_timeout_us.max(100)));
    let timeouts = Timeouts {
        pdu: pdu_timeout,
        state_transition: Duration::from_millis(u64::from(state_timeout_ms.max(100))),
        wait_loop_delay: Duration::from_millis(1),
        // ethercrab's 10 ms for an EEPROM (SII) read, polled every wait_loop_delay, is less
        // than one frame may take here (the frame timeout): a host that delays one poll's
        // frame by 10 ms failed the boot with `timeout: EEPROM` (ecat_replay, 2026-11-27).
        // Two frame timeouts: a read survives one frame as late as a frame may be.
        eeprom: (2 * pdu_timeout).max(Timeouts::default().eeprom),
        ..Timeouts::default()
    };
    let config =
        MainDeviceConfig { retry_behaviour: RetryBehaviour::None, dc_static_sync_iterations: DC_STATIC_SYNC_FRAMES };
    let md: &'static MainDevice<'static> = Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts, config)));
    Box::into_raw(Box::new(SsEcatMaster {
        md,
        preop: None,
        safe: None,
        op: None,
        expected_wkc: 0,
        pdu_timeout,
        io,
        addresses: [0; MAX_SUBDEVICES],
        n_addresses: 0,
        error: [0; 256],
    }))
}

/// The last error of `ss_ecat_scan` / `ss_ecat_to_op` / `ss_ecat_exchange`.
///
/// # Safety
/// `m` comes from `ss_ecat_open`.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_error(m: *const SsEcatMaster) -> *const c_char {
    if m.is_null() {
        return c"no master".as_ptr();
    }
    (*m).error.as_ptr() as *const c_char
}

/// Copies what the master knows of each subdevice into `subs` (up to `max`, bus order).
///
/// # Safety
/// `subs` points to `max` entries (or is null).
unsafe fn describe<'a, S: core::ops::Deref<Target = ethercrab::SubDevice>>(
    subdevices: impl Iterator<Item = ethercrab::SubDeviceRef<'a, S>>,
    mut bytes: impl FnMut(&ethercrab::SubDeviceRef<'a, S>) -> (u16, u16),
    subs: *mut SsEcatSub,
    max: usize,
) -> usize {
    let mut n = 0usize;
    for sd in subdevices {
        let id = sd.identity();
        let (in_bytes, out_bytes) = bytes(&sd);
        if n < max && !subs.is_null() {
            let mut name = [0 as c_char; 64];
            for (d, s) in name.iter_mut().zip(sd.name().bytes().take(63)) {
                *d = s as c_char;
            }
            *subs.add(n) = SsEcatSub {
                vendor_id: id.vendor_id,
                product_code: id.product_id,
                revision: id.revision,
                serial: id.serial,
                configured_address: sd.configured_address(),
                in_bytes,
                out_bytes,
                name,
            };
        }
        n += 1;
    }
    n
}

/// Scans the bus, reads every SII, configures the mailboxes and brings the subdevices to
/// PRE-OP, where their start-up SDOs go (`ss_ecat_sdo_write`). Fills up to `max` entries of
/// `subs` in bus order (identities; no PDO sizes yet: `ss_ecat_to_safe_op` maps them);
/// returns the number of subdevices found, or -1.
///
/// # Safety
/// `m` comes from `ss_ecat_open`; `subs` points to `max` entries.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_scan(m: *mut SsEcatMaster, subs: *mut SsEcatSub, max: usize) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let md = m.md;
    let group = match block_on(md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercat_now)) {
        Ok(g) => g,
        Err(e) => return m.fail(&format!("scan: {}", e)),
    };
    let n = describe(group.iter(md), |_| (0, 0), subs, max);
    m.n_addresses = 0;
    for (i, sd) in group.iter(md).take(MAX_SUBDEVICES).enumerate() {
        m.addresses[i] = sd.configured_address();
        m.n_addresses = i + 1;
    }
    m.preop = Some(group);
    n as i32
}

/// The AL status (0x0130: the state in bits 0-3, bit 4 the error indication) and the AL
/// status code (0x0134) of the subdevice at `position` (0-based, bus order), read with one
/// FPRD each. 0, or -1 with the reason in `ss_ecat_error`. Allocates nothing; waits for up to
/// two frame round trips (each bounded by the PDU timeout): not for the real-time cycle.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned; `status` and `code` are null or writable.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_al_status(m: *mut SsEcatMaster, position: u16, status: *mut u16, code: *mut u16) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let Some(address) = m.address(position) else {
        return m.fail(&format!("no subdevice {}", usize::from(position) + 1));
    };
    let md = m.md;
    let r: Result<(u16, u16), EcError> = block_on(async {
        let s: u16 = Command::fprd(address, RegisterAddress::AlStatus.into()).receive(md).await?;
        let c: u16 = Command::fprd(address, RegisterAddress::AlStatusCode.into()).receive(md).await?;
        Ok((s, c))
    });
    match r {
        Ok((s, c)) => {
            if let Some(p) = status.as_mut() {
                *p = s;
            }
            if let Some(p) = code.as_mut() {
                *p = c;
            }
            0
        }
        Err(e) => m.fail(&format!("subdevice {}: reading its AL status: {}", usize::from(position) + 1, e)),
    }
}

/// Writes `control` into the AL control register (0x0120) of the subdevice at `position`
/// (0-based): the requested state in bits 0-3 (1 INIT, 2 PRE-OP, 4 SAFE-OP, 8 OP), bit 4
/// acknowledges an error indication of its AL status (ETG.1000.6 6.4.1: while the error is
/// shown, a request without it is ignored). Does not wait for the state: the caller reads it
/// back (the cyclic exchange's AL states, or `ss_ecat_al_status`). 0, or -1 with the reason.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_al_control(m: *mut SsEcatMaster, position: u16, control: u16) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    if control & !0x001F != 0 || !matches!(control & 0x0F, 1 | 2 | 4 | 8) {
        return m.fail(&format!("AL control {:#06x}: a state 1, 2, 4 or 8 and the acknowledge bit 0x10 only", control));
    }
    let Some(address) = m.address(position) else {
        return m.fail(&format!("no subdevice {}", usize::from(position) + 1));
    };
    let md = m.md;
    match block_on(Command::fpwr(address, RegisterAddress::AlControl.into()).send_receive::<u16>(md, control)) {
        Ok(_) => 0,
        Err(e) => m.fail(&format!("subdevice {}: writing AL control {:#06x}: {}", usize::from(position) + 1, control, e)),
    }
}

/// One SDO download of a start-up list, in PRE-OP, to the subdevice at `position` (0-based):
/// `size` (1, 2 or 4) bytes of `value` to `index`:`sub`, then an upload of the same object
/// to see that it holds the value (skipped when the object cannot be read: abort 0x06010001).
/// 0, or -1 with the reason in `ss_ecat_error` and, when the subdevice refused with an SDO
/// abort, its code in `*abort` (else 0 there) and the code's standard text as the reason.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned; `abort` is null or writable.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_sdo_write(
    m: *mut SsEcatMaster,
    position: u16,
    index: u16,
    sub: u8,
    value: u32,
    size: u8,
    abort: *mut u32,
) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    if let Some(a) = abort.as_mut() {
        *a = 0;
    }
    let md = m.md;
    let Some(group) = m.preop.as_ref() else { return m.fail("not scanned (SDOs go in PRE-OP)") };
    let sd = match group.subdevice(md, usize::from(position)) {
        Ok(sd) => sd,
        Err(e) => return m.fail(&format!("no subdevice {}: {}", usize::from(position) + 1, e)),
    };
    let r: Result<Option<u32>, EcError> = block_on(async {
        match size {
            1 => sd.sdo_write(index, sub, value as u8).await?,
            2 => sd.sdo_write(index, sub, value as u16).await?,
            4 => sd.sdo_write(index, sub, value).await?,
            _ => return Err(EcError::Internal),
        }
        let back: Result<u32, EcError> = match size {
            1 => sd.sdo_read::<u8>(index, sub).await.map(u32::from),
            2 => sd.sdo_read::<u16>(index, sub).await.map(u32::from),
            _ => sd.sdo_read::<u32>(index, sub).await,
        };
        match back {
            Ok(v) => Ok(Some(v)),
            Err(EcError::Mailbox(MailboxError::Aborted { code, .. })) if u32::from(code) == 0x0601_0001 => Ok(None),
            Err(e) => Err(e),
        }
    });
    match r {
        Ok(Some(v)) if v != value => {
            m.fail(&format!("SDO {:#06x}:{:02x} reads back {:#x} after writing {:#x}", index, sub, v, value))
        }
        Ok(_) => 0,
        Err(EcError::Mailbox(MailboxError::Aborted { code, .. })) => {
            if let Some(a) = abort.as_mut() {
                *a = u32::from(code);
            }
            // The standard text alone (ethercrab's Display is "0x...: text"): the caller names
            // the object and the code.
            let text = code.to_string();
            let text = text.split_once(": ").map_or(text.as_str(), |(_, t)| t).trim().to_owned();
            m.fail(&text)
        }
        Err(e) if size != 1 && size != 2 && size != 4 => m.fail(&format!("SDO size {} (1, 2 or 4): {}", size, e)),
        Err(e) => m.fail(&format!("SDO {:#06x}:{:02x}: {}", index, sub, e)),
    }
}

/// Maps the PDOs (from the SII, or by SDO from the PDO assignment of a subdevice with CoE)
/// and brings the subdevices from PRE-OP to SAFE-OP (outputs still safe). Fills `subs` as
/// `ss_ecat_scan` does, now with the PDO sizes; returns the number of subdevices, or -1.
///
/// Distributed clocks: `assign_activate` holds `n_assign` words in bus order (the ESI's
/// AssignActivate, 0 = free run). When one is non-zero, SYNC0 is configured on those
/// subdevices (0x0981 activation, 0x0990 start time `DC_START_DELAY` ahead, 0x09A0 =
/// `sync0_ns`) in PRE-OP, and every exchange carries the FRMW of the reference clock's system
/// time (ethercrab's `tx_rx_dc`). The reference clock (the first subdevice with a DC unit),
/// the propagation delays and the offsets were set by the scan. SYNC1 (0x0400) is refused.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned; `subs` points to `max` entries;
/// `assign_activate` to `n_assign` words (or is null with `n_assign` 0).
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_to_safe_op(
    m: *mut SsEcatMaster,
    subs: *mut SsEcatSub,
    max: usize,
    assign_activate: *const u16,
    n_assign: usize,
    sync0_ns: u32,
    shift_ns: u32,
) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let md = m.md;
    let Some(mut group) = m.preop.take() else { return m.fail("not scanned") };
    let assign = if assign_activate.is_null() { &[][..] } else { core::slice::from_raw_parts(assign_activate, n_assign) };
    let dc = assign.iter().any(|&a| a != 0);
    let mut refused: Option<String> = None;
    for (i, mut sd) in group.iter_mut(md).enumerate() {
        let aa = assign.get(i).copied().unwrap_or(0);
        if aa == 0 {
            continue;
        }
        if aa & 0x0400 != 0 {
            refused = Some(format!("subdevice {}: AssignActivate {:#06x} asks for SYNC1, which this master does not configure", i + 1, aa));
        } else if aa & 0x0200 == 0 {
            refused = Some(format!("subdevice {}: AssignActivate {:#06x} activates no SYNC0", i + 1, aa));
        } else if !sd.dc_support().enhanced() {
            refused = Some(format!("subdevice {} ({}): configured for DC but it has no DC SYNC unit", i + 1, sd.name()));
        }
        if refused.is_some() {
            break;
        }
        sd.set_dc_sync(DcSync::Sync0);
    }
    if let Some(msg) = refused {
        m.preop = Some(group);
        return m.fail(&msg);
    }
    let safe = if dc {
        let conf = DcConfiguration {
            start_delay: DC_START_DELAY,
            sync0_period: Duration::from_nanos(u64::from(sync0_ns)),
            sync0_shift: Duration::from_nanos(u64::from(shift_ns)),
        };
        let r = block_on(async {
            group.into_pre_op_pdi(md).await?.configure_dc_sync(md, conf).await?.into_safe_op(md).await
        });
        match r {
            Ok(g) => Safe::Dc(g),
            Err(e) => return m.fail(&format!("PRE-OP -> SAFE-OP with distributed clocks: {}", e)),
        }
    } else {
        match block_on(group.into_safe_op(md)) {
            Ok(g) => Safe::Free(g),
            Err(e) => return m.fail(&format!("PRE-OP -> SAFE-OP: {}", e)),
        }
    };
    let mut expected = 0u16;
    let n = on_group!(&safe, Safe, group => describe(
        group.iter(md),
        |sd| {
            let (i, o) = (sd.inputs_raw().len() as u16, sd.outputs_raw().len() as u16);
            expected += u16::from(i > 0) + 2 * u16::from(o > 0);
            (i, o)
        },
        subs,
        max,
    ));
    m.expected_wkc = expected;
    m.safe = Some(safe);
    n as i32
}

/// The position (1-based) of the DC reference clock: the first subdevice with a DC unit, as
/// ethercrab chooses it; 0 when none has one.
///
/// # Safety
/// `m` comes from `ss_ecat_open`.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_dc_reference(m: *const SsEcatMaster) -> i32 {
    let Some(m) = m.as_ref() else { return 0 };
    let md = m.md;
    let pos = match (&m.preop, &m.safe, &m.op) {
        (Some(g), _, _) => g.iter(md).position(|sd| sd.dc_support().any()),
        (_, Some(s), _) => on_group!(s, Safe, g => g.iter(md).position(|sd| sd.dc_support().any())),
        (_, _, Some(o)) => on_group!(o, Running, g => g.iter(md).position(|sd| sd.dc_support().any())),
        _ => None,
    };
    pos.map_or(0, |p| p as i32 + 1)
}

/// The process-data watchdog of every subdevice (ETG.1000.4 6.3): `divider` into 0x0400
/// (ticks of (divider + 2) x 40 ns) and `time` ticks into 0x0420. A subdevice whose outputs
/// are not written for that long puts them in their safe state by itself: the contactor
/// opens and the drives lose their enable when this master dies. Written in SAFE-OP,
/// before OP (where the watchdog starts counting), and read back. 0 or -1.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_set_watchdog(m: *mut SsEcatMaster, divider: u16, time: u16) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let md = m.md;
    let Some(safe) = m.safe.as_ref() else { return m.fail("not scanned") };
    let mut failed: Option<String> = None;
    // Written in bus order, read back (allocates: start-up only).
    let results: Vec<Result<(u16, u16), EcError>> = on_group!(safe, Safe, group => group
        .iter(md)
        .map(|sd| {
            block_on(async {
                sd.register_write(0x0400u16, divider).await?;
                sd.register_write(0x0420u16, time).await?;
                let d: u16 = sd.register_read(0x0400u16).await?;
                let t: u16 = sd.register_read(0x0420u16).await?;
                Ok::<(u16, u16), EcError>((d, t))
            })
        })
        .collect());
    for (i, r) in results.into_iter().enumerate() {
        match r {
            Ok((d, t)) if d == divider && t == time => {}
            Ok((d, t)) => {
                failed = Some(format!(
                    "subdevice {}: process-data watchdog reads back divider {} time {}, written {} {}",
                    i + 1,
                    d,
                    t,
                    divider,
                    time
                ));
                break;
            }
            Err(e) => {
                failed = Some(format!("subdevice {}: writing the process-data watchdog: {}", i + 1, e));
                break;
            }
        }
    }
    match failed {
        Some(msg) => m.fail(&msg),
        None => 0,
    }
}

/// SAFE-OP -> OP for every subdevice (with DC: requested, not waited for; see below). 0 or -1.
///
/// # Safety
/// `m` comes from `ss_ecat_open` and was scanned.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_to_op(m: *mut SsEcatMaster) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let Some(safe) = m.safe.take() else { return m.fail("not scanned") };
    // With DC the drives enter OP at their first SYNC0 pulse (up to DC_START_DELAY after the
    // SYNC configuration): OP is only requested here, and the caller exchanges process data
    // every cycle until every subdevice shows OP (the free-running ones are in OP at once,
    // their process-data watchdogs counting: they must not wait for the drives' first pulse).
    let r = match safe {
        Safe::Free(g) => block_on(g.into_op(m.md)).map(Running::Free),
        Safe::Dc(g) => block_on(g.request_into_op(m.md)).map(Running::Dc),
    };
    match r {
        Ok(g) => {
            m.op = Some(g);
            0
        }
        Err(e) => m.fail(&format!("SAFE-OP -> OP: {}", e)),
    }
}

/// One cyclic exchange: writes `outputs` (every subdevice's output bytes in bus order,
/// concatenated), sends one LRW (with the AL status checks in the same frame), waits for
/// it, and copies the inputs (concatenated likewise) into `inputs`. Returns 0, or -1 when
/// the frame did not come back in time or could not be sent. No allocation.
///
/// `timeout_us` > 0 bounds the wait for this exchange below the PDU timeout (the scan
/// cycle's budget): when it passes, the frame in flight is given up (its slot is released;
/// an answer coming later is a stray frame, dropped by the frame thread) and the inputs
/// stay as they were (a stale cycle). 0: wait up to the PDU timeout.
///
/// `drive` != 0: the calling thread sends and receives itself, sleeping on the socket
/// (`run_until`); 0: it parks until the frame thread wakes it or the deadline passes.
///
/// # Safety
/// `m` comes from `ss_ecat_open`; the buffers hold `out_len` / `in_len` bytes.
#[no_mangle]
pub unsafe extern "C" fn ss_ecat_exchange(
    m: *mut SsEcatMaster,
    outputs: *const u8,
    out_len: usize,
    inputs: *mut u8,
    in_len: usize,
    cycle: *mut SsEcatCycle,
    timeout_us: u32,
    drive: u32,
) -> i32 {
    let Some(m) = m.as_mut() else { return -1 };
    let md = m.md;
    let Some(running) = m.op.as_ref() else { return -1 };
    let outs = if outputs.is_null() { &[][..] } else { core::slice::from_raw_parts(outputs, out_len) };
    let mut off = 0usize;
    on_group!(running, Running, group => for sd in group.iter(md) {
        let mut o = sd.outputs_raw_mut();
        let k = o.len().min(outs.len().saturating_sub(off));
        o[..k].copy_from_slice(&outs[off..off + k]);
        off += o.len();
    });
    // Past the deadline the future is dropped, which releases its frame (ethercrab's
    // ReceiveFrameFut::drop) and the PDI lock; the PDI (our inputs) is only written from a
    // frame that came back.
    let wait = if timeout_us == 0 { m.pdu_timeout } else { Duration::from_micros(u64::from(timeout_us)) };
    let io = (drive != 0).then_some(&*m.io);
    let deadline = Instant::now() + wait;
    // (working counter, AL states, DC time): the FRMW of the reference clock's system time
    // rides in the same frame as the LRW when the group has DC.
    let states = |s: &[SubDeviceState]| {
        let mut a = [0u8; MAX_SUBDEVICES];
        for (d, st) in a.iter_mut().zip(s.iter()) {
            *d = state_code(*st);
        }
        (a, s.len() as u16)
    };
    let result: Result<(u16, AlStates, u64), EcError> = match running {
        Running::Free(group) => run_until(group.tx_rx(md), deadline, io)
            .unwrap_or(Err(EcError::Timeout(ethercrab::error::TimeoutError::Pdu)))
            .map(|r| (r.working_counter, states(&r.subdevice_states), 0)),
        Running::Dc(group) => run_until(group.tx_rx_dc(md), deadline, io)
            .unwrap_or(Err(EcError::Timeout(ethercrab::error::TimeoutError::Pdu)))
            .map(|r| (r.working_counter, states(&r.subdevice_states), r.extra.dc_system_time)),
    };
    let ins = if inputs.is_null() { &mut [][..] } else { core::slice::from_raw_parts_mut(inputs, in_len) };
    let mut off = 0usize;
    on_group!(running, Running, group => for sd in group.iter(md) {
        let i = sd.inputs_raw();
        let k = i.len().min(ins.len().saturating_sub(off));
        ins[off..off + k].copy_from_slice(&i[..k]);
        off += i.len();
    });
    let Some(c) = cycle.as_mut() else { return if result.is_ok() { 0 } else { -1 } };
    c.expected_wkc = m.expected_wkc;
    c.al_state = [0; MAX_SUBDEVICES];
    match result {
        Ok((wkc, (al, count), dc_time)) => {
            c.wkc = wkc;
            c.count = count;
            c.dc_time = dc_time;
            c.al_state = al;
            0
        }
        Err(_) => {
            c.wkc = 0;
            c.count = 0;
            c.dc_time = 0;
            -1
        }
    }
}

/// Frames received that matched no PDU in flight (late after their timeout, or corrupted):
/// counted and dropped by the frame thread, which carries on.
#[no_mangle]
pub extern "C" fn ss_ecat_stray_frames() -> u64 {
    txrx::STRAY_FRAMES.load(std::sync::atomic::Ordering::Relaxed)
}

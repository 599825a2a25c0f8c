"""OPC 40010-1 (Robotics) server tests (docs/opcua.md), from outside, with an independent
OPC UA client (asyncua) against a real `safestate run` on the simulated cell: the adapter
started and supervised by `safestate run`, the physical world driven through the gateway's
`sim` messages from a loopback pendant, as in test_gateway.py.

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_opcua.py
"""

import asyncio
import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from asyncua import Client as UaClient
from asyncua import ua

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gateway import (  # noqa: E402
    ROOT, SafeState, booted, free_port, get_json, run, to_t1_manual_idle, try_status, wait_until,
)

ROBOTICS = "http://opcfoundation.org/UA/Robotics/"
DI = "http://opcfoundation.org/UA/DI/"
OWN = "urn:safestate:opcua"
ADAPTER = ROOT / "adapters" / "opcua" / "dist" / "main.js"
USER, PASSWORD = "plc", "correct horse battery staple"
# Issue 14's goal, a subscription sees EmergencyStop within 200 ms of a press, is a time figure:
# bench/opcua_estop.py measures it (docs/performance.md, idle and with every core busy). This
# functional test asserts that the notification comes, with a margin above the bench's loaded
# maximum for a host stall of this shared VM (issue 40: 201.9 ms once, in a full `make test`).
ESTOP_NOTIFY_MARGIN_S = 1.0


def users_file(path):
    salt = os.urandom(16)
    key = hashlib.scrypt(PASSWORD.encode(), salt=salt, n=16384, r=8, p=1, dklen=32)
    path.write_text(f"# test users\n{USER}:scrypt:{salt.hex()}:{key.hex()}\n")
    return path


class OpcCell:
    """`safestate run` with its OPC UA adapter on a free port."""

    def __init__(self, tmp_path, args=()):
        if not ADAPTER.exists():
            pytest.fail(f"{ADAPTER} missing: `make opcua` builds the adapter")
        self.opc_port = free_port()
        self.users = users_file(tmp_path / "opcua-users")
        self.cell = SafeState(tmp_path, args=["--opcua-port", str(self.opc_port),
                                              "--opcua-users-file", str(self.users), *args])
        self.url = f"opc.tcp://127.0.0.1:{self.opc_port}"
        try:
            run(self.wait_served())
        except BaseException:
            self.cell.stop()
            raise

    async def wait_served(self):
        deadline = time.monotonic() + 30
        while True:
            try:
                async with UaClient(self.url, timeout=2) as c:
                    n = await Nodes.of(c)
                    estop = await n.estop_node()
                    if (await estop.read_data_value(raise_on_bad_status=False)).StatusCode.is_good():
                        return
            except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError):
                pass
            assert self.cell.proc.poll() is None, self.cell.output()
            assert time.monotonic() < deadline, f"OPC UA not served at {self.url}: {self.cell.output()}"
            await asyncio.sleep(0.3)


@pytest.fixture
def opc(tmp_path):
    s = OpcCell(tmp_path)
    yield s
    code = s.cell.stop()
    assert code == 0, f"safestate run exited {code} after SIGINT: {s.cell.output()}"


def client(url, user=False):
    c = UaClient(url, timeout=5)
    if user:
        c.set_user(USER)
        c.set_password(PASSWORD)
    return c


class Nodes:
    """The nodes of the address space, found by browse names as in the OPC 40010-1 nodeset."""

    def __init__(self, c, rob, di, own):
        self.c, self.rob, self.di, self.own = c, rob, di, own

    @classmethod
    async def of(cls, c):
        ns = [await c.get_namespace_index(u) for u in (ROBOTICS, DI, OWN)]
        return cls(c, *ns)

    def mds(self):
        return self.c.get_node(ua.ObjectIds.ObjectsFolder)

    def path(self, *names):
        return [f"{self.own}:MotionDeviceSystem", *names]

    async def get(self, *names):
        return await self.mds().get_child(self.path(*names))

    def safety(self, var):
        return self.get(f"{self.rob}:SafetyStates", f"{self.own}:SafetyState", f"{self.di}:ParameterSet",
                        f"{self.rob}:{var}")

    async def estop_node(self):
        return await self.safety("EmergencyStop")

    async def own_var(self, name):
        return await self.get(f"{self.own}:SafeState", f"{self.own}:{name}")

    async def task_control(self):
        return await self.get(f"{self.rob}:Controllers", f"{self.own}:Controller", f"{self.rob}:TaskControls",
                              f"{self.own}:TaskControl")


def unece(code):
    """UnitId of a UNECE common code (OPC 10000-8 §5.6.3)."""
    v = 0
    for ch in code:
        v = (v << 8) | ord(ch)
    return v


async def name_of(node):
    return (await node.read_browse_name()).to_string()


async def children_names(node):
    return {await name_of(ch) for ch in await node.get_children()}


async def wait_value(node, pred, timeout=10.0, what="a value"):
    deadline = time.monotonic() + timeout
    while True:
        dv = await node.read_data_value(raise_on_bad_status=False)
        if pred(dv):
            return dv
        assert time.monotonic() < deadline, f"timeout waiting for {what}; last {dv}"
        await asyncio.sleep(0.05)


async def call(c, obj, method, *args):
    """(status code name, output arguments) of one Call, without asyncua raising on Bad."""
    req = ua.CallMethodRequest()
    req.ObjectId = obj.nodeid
    req.MethodId = method.nodeid
    req.InputArguments = [ua.Variant(a, ua.VariantType.String) if isinstance(a, str) else ua.Variant(a)
                          for a in args]
    [res] = await c.uaclient.call([req])
    return res.StatusCode.name, [v.Value for v in (res.OutputArguments or [])]


# ---------------------------------------------------------------------------- tests
def test_browse_from_objects_to_the_mandatory_folders_with_the_nodeset_names(opc):
    async def main():
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            objects = c.get_node(ua.ObjectIds.ObjectsFolder)
            mds_type = ua.NodeId(1002, n.rob)  # MotionDeviceSystemType in the Robotics nodeset
            systems = [ch for ch in await objects.get_children()
                       if await ch.read_type_definition() == mds_type]
            assert len(systems) == 1, "exactly one MotionDeviceSystem under Objects"
            mds = systems[0]
            names = await children_names(mds)
            for folder in ("MotionDevices", "Controllers", "SafetyStates"):
                assert f"{n.rob}:{folder}" in names, (folder, names)
            # The same system in DI's DeviceSet, where OPC 40010-1 places it.
            device_set = await objects.get_child([f"{n.di}:DeviceSet"])
            assert mds.nodeid in [ch.nodeid for ch in await device_set.get_children()]

            safety = await mds.get_child([f"{n.rob}:SafetyStates", f"{n.own}:SafetyState"])
            params = await children_names(await safety.get_child([f"{n.di}:ParameterSet"]))
            assert {f"{n.rob}:EmergencyStop", f"{n.rob}:ProtectiveStop", f"{n.rob}:OperationalMode"} <= params
            for folder, fields in (("EmergencyStopFunctions", {"Name", "Active"}),
                                   ("ProtectiveStopFunctions", {"Name", "Enabled", "Active"})):
                [fn] = await (await safety.get_child([f"{n.rob}:{folder}"])).get_children()
                assert {f"{n.rob}:{f}" for f in fields} <= await children_names(fn), folder

            robot = await mds.get_child([f"{n.rob}:MotionDevices", f"{n.own}:Robot"])
            assert await (await robot.get_child([f"{n.rob}:MotionDeviceCategory"])).read_value() == 1  # ARTICULATED
            assert "simulated" in (await (await robot.get_child([f"{n.di}:Manufacturer"])).read_value()).Text
            override = await robot.get_child([f"{n.di}:ParameterSet", f"{n.rob}:SpeedOverride"])
            assert await override.read_value() == 100.0
            axes = await (await robot.get_child([f"{n.rob}:Axes"])).get_children()
            assert len(axes) == 6
            status = get_json(opc.cell.port, "/api/status")
            for i in range(6):
                p = await robot.get_child([f"{n.rob}:Axes", f"{n.own}:Axis{i + 1}", f"{n.di}:ParameterSet"])
                pos = await p.get_child([f"{n.rob}:ActualPosition"])
                speed = await p.get_child([f"{n.rob}:ActualSpeed"])
                # UNECE Rec. 20 codes, as OPC 10000-8 requires: DD degree, E96 degree per second.
                eu = await (await pos.get_child(["0:EngineeringUnits"])).read_value()
                assert (eu.UnitId, eu.DisplayName.Text) == (unece("DD"), "°"), eu
                eu = await (await speed.get_child(["0:EngineeringUnits"])).read_value()
                assert (eu.UnitId, eu.DisplayName.Text) == (unece("E96"), "°/s"), eu
                assert abs(await pos.read_value() - status["joints"][i] * 180 / 3.141592653589793) < 0.01
                assert await speed.read_value() == 0.0, "the arm is at rest"
                train = await robot.get_child([f"{n.rob}:PowerTrains", f"{n.own}:PowerTrain{i + 1}"])
                motor = await train.get_child([f"{n.own}:Motor{i + 1}"])
                brake = await motor.get_child([f"{n.di}:ParameterSet", f"{n.rob}:BrakeReleased"])
                assert await brake.read_value() is False, "brakes engaged at rest"
                drive = await train.get_child([f"{n.own}:Drive{i + 1}"])
                assert await drive.read_type_definition() == ua.NodeId(17793, n.rob)  # DriveType

            controller = await mds.get_child([f"{n.rob}:Controllers", f"{n.own}:Controller"])
            rev = await controller.get_child([f"{n.rob}:Software", f"{n.own}:SafeState", f"{n.di}:SoftwareRevision"])
            assert (await rev.read_value()) != ""
            tc = await n.task_control()
            p = await tc.get_child([f"{n.di}:ParameterSet"])
            assert await (await p.get_child([f"{n.rob}:TaskProgramName"])).read_value() == "demo"
            assert await (await p.get_child([f"{n.rob}:TaskProgramLoaded"])).read_value() is True
            assert await (await tc.get_child([f"{n.own}:ExecutionState"])).read_value() == "Idle"

            own = await mds.get_child([f"{n.own}:SafeState"])
            assert {f"{n.own}:{v}" for v in ("state", "sub", "stop", "first_out_cause", "Alarms")} <= \
                await children_names(own)
            assert await (await n.own_var("state")).read_value() == status["state"]
    run(main())


def test_every_value_is_read_only_and_anonymous_may_not_call(opc):
    async def main():
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            estop = await n.estop_node()
            with pytest.raises(ua.UaStatusCodeError) as e:
                await estop.write_value(ua.DataValue(ua.Variant(False, ua.VariantType.Boolean)))
            assert e.value.code == ua.StatusCodes.BadNotWritable
            writes = [
                (await n.own_var("state"), ua.Variant("IDLE", ua.VariantType.String)),
                (await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:names"),
                 ua.Variant(["X"], ua.VariantType.String)),
                (await n.get(f"{n.rob}:MotionDevices", f"{n.own}:Robot", f"{n.di}:Manufacturer"),
                 ua.Variant(ua.LocalizedText("X"), ua.VariantType.LocalizedText)),
                (await n.get(f"{n.rob}:MotionDevices", f"{n.own}:Robot", f"{n.di}:ParameterSet",
                             f"{n.rob}:SpeedOverride"), ua.Variant(50.0, ua.VariantType.Double)),
            ]
            for node, value in writes:
                with pytest.raises(ua.UaStatusCodeError) as e:
                    await node.write_value(ua.DataValue(value))
                assert e.value.code == ua.StatusCodes.BadNotWritable, node
            tc = await n.task_control()
            start = await tc.get_child([f"{n.own}:Start"])
            code, _ = await call(c, tc, start)
            assert code in ("BadUserAccessDenied", "BadNotExecutable"), code
            # Nothing that only the pendant may do is reachable: these four are all there is.
            methods = {await name_of(m) for m in await tc.get_methods()}
            assert methods == {f"{n.own}:{m}" for m in ("Start", "Stop", "Pause", "Resume")}, methods
        s = get_json(opc.cell.port, "/api/status")
        assert s["state"] == "ESTOP_RESET_NEEDED", "an anonymous call changed nothing"
    run(main())


async def hierarchy_variables(c):
    """NodeIds of every Variable reachable from Root over hierarchical references: the
    nodesets' type definitions and their children, the Server object's diagnostics, this
    session's and its subscriptions' diagnostics, SafeState's nodes."""
    root = ua.NodeId(ua.ObjectIds.RootFolder)
    seen, frontier, variables = {root.to_string()}, [root], []

    def take(refs):
        for ref in refs:
            nid = ua.NodeId(ref.NodeId.Identifier, ref.NodeId.NamespaceIndex, ref.NodeId.NodeIdType)
            if nid.to_string() in seen:
                continue
            seen.add(nid.to_string())
            frontier.append(nid)
            if ref.NodeClass == ua.NodeClass.Variable:
                variables.append(nid)

    while frontier:
        batch, frontier[:] = frontier[:1000], frontier[1000:]
        params = ua.BrowseParameters()
        params.RequestedMaxReferencesPerNode = 0
        params.NodesToBrowse = []
        for nid in batch:
            d = ua.BrowseDescription()
            d.NodeId, d.BrowseDirection = nid, ua.BrowseDirection.Forward
            d.ReferenceTypeId, d.IncludeSubtypes = ua.NodeId(ua.ObjectIds.HierarchicalReferences), True
            d.NodeClassMask, d.ResultMask = 0, 63
            params.NodesToBrowse.append(d)
        for r in await c.uaclient.browse(params):
            take(r.References)
            cp = r.ContinuationPoint
            while cp:
                nxt = ua.BrowseNextParameters()
                nxt.ContinuationPoints = [cp]
                [more] = await c.uaclient.browse_next(nxt)
                take(more.References)
                cp = more.ContinuationPoint
    return variables


async def read_attribute(c, nodes, attribute):
    """DataValues of one attribute of many nodes; None for a value asyncua cannot decode (it
    fails on some empty matrices of the nodesets), found by halving the failing batch."""
    if not nodes:
        return []
    params = ua.ReadParameters()
    params.NodesToRead = []
    for nid in nodes:
        r = ua.ReadValueId()
        r.NodeId, r.AttributeId = nid, attribute
        params.NodesToRead.append(r)
    try:
        return await c.uaclient.read(params)
    except (ua.UaStatusCodeError, asyncio.TimeoutError, ConnectionError):
        raise
    except Exception:  # a decoding error of asyncua's (IndexError, NotEnoughData, ...)
        if len(nodes) == 1:
            return [None]
        half = len(nodes) // 2
        return await read_attribute(c, nodes[:half], attribute) + await read_attribute(c, nodes[half:], attribute)


async def read_many(c, nodes, attribute):
    out = []
    for i in range(0, len(nodes), 1000):
        out += await read_attribute(c, nodes[i:i + 1000], attribute)
    return out


def test_no_anonymous_write_succeeds_anywhere_in_the_address_space(opc):
    """Every Variable of the address space, written with its own current value by an anonymous
    session: none accepts (issue 24: ServerDiagnostics/EnabledFlag, type-definition children
    and session diagnostics did), and none claims CurrentWrite in its UserAccessLevel."""
    async def main():
        p = await booted(opc.cell)
        assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"  # an alarm condition exists
        await p.state("ESTOP_ACTIVE")
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            await wait_value(await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:names"),
                             lambda dv: dv.StatusCode.is_good() and "ESTOP_PRESSED" in (dv.Value.Value or []),
                             what="ESTOP_PRESSED among the alarms")
            sub = await c.create_subscription(100, object())  # its diagnostics are variables too
            started = time.monotonic()
            variables = await hierarchy_variables(c)
            condition = await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:ESTOP_PRESSED")
            names = {v.to_string() for v in variables}
            for must in (ua.NodeId(ua.ObjectIds.Server_ServerDiagnostics_EnabledFlag),
                         (await condition.get_child(["0:ActiveState", "0:Id"])).nodeid,
                         (await n.estop_node()).nodeid):
                assert must.to_string() in names, must
            sessions = c.get_node(ua.ObjectIds.Server_ServerDiagnostics_SessionsDiagnosticsSummary)
            assert len(await sessions.get_children()) > 2, "this session's diagnostics are walked"
            values = await read_many(c, variables, ua.AttributeIds.Value)
            levels = await read_many(c, variables, ua.AttributeIds.UserAccessLevel)
            undecodable = sum(dv is None for dv in values)
            # What asyncua cannot decode is written back as an empty value: still a write.
            values = [dv if dv is not None else ua.DataValue(ua.Variant()) for dv in values]
            writable = [nid.to_string() for nid, lv in zip(variables, levels)
                        if lv is None or (lv.StatusCode.is_good() and lv.Value.Value & ua.AccessLevel.CurrentWrite.mask)]
            accepted, refusals = [], {}
            for i in range(0, len(variables), 1000):
                params = ua.WriteParameters()
                params.NodesToWrite = []
                for nid, dv in zip(variables[i:i + 1000], values[i:i + 1000]):
                    w = ua.WriteValue()
                    w.NodeId, w.AttributeId, w.Value = nid, ua.AttributeIds.Value, ua.DataValue(dv.Value)
                    params.NodesToWrite.append(w)
                for w, code in zip(params.NodesToWrite, await c.uaclient.write(params)):
                    refusals[code.name] = refusals.get(code.name, 0) + 1
                    if code.name not in ("BadUserAccessDenied", "BadNotWritable"):
                        accepted.append((w.NodeId.to_string(), code.name))
            print(f"{len(variables)} variables written anonymously in {time.monotonic() - started:.1f} s "
                  f"({undecodable} with a value asyncua cannot decode, written empty): {refusals}")
            assert len(variables) > 1000, len(variables)
            assert accepted == [], f"{len(accepted)} anonymous writes not refused: {accepted[:20]}"
            assert writable == [], f"{len(writable)} variables say an anonymous user may write: {writable[:20]}"
            flag = c.get_node(ua.ObjectIds.Server_ServerDiagnostics_EnabledFlag)
            assert (await flag.read_value()) == values[[v.to_string() for v in variables].index(
                flag.nodeid.to_string())].Value.Value, "EnabledFlag unchanged"
            await sub.delete()
        await p.close()
    run(main())


def test_emergency_stop_reads_the_button_in_lockout_too(opc):
    """EmergencyStop and the E-stop function's Active follow the button (the alarm ESTOP_PRESSED,
    active exactly while it is pressed, SPEC §7), not the state: in ERROR_LOCKOUT too."""
    async def main():
        p = await booted(opc.cell)
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            estop = await n.estop_node()
            active = await n.get(f"{n.rob}:SafetyStates", f"{n.own}:SafetyState", f"{n.rob}:EmergencyStopFunctions",
                                 f"{n.own}:EmergencyStopCircuit", f"{n.rob}:Active")

            async def both(value, what):
                for node in (estop, active):
                    await wait_value(node, lambda dv: dv.StatusCode.is_good() and dv.Value.Value is value, what=what)

            await both(False, "released after boot")
            assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
            await p.state("ESTOP_ACTIVE")
            await both(True, "pressed")
            # Locked out while the button is held (issue 24: the state alone said "no E-stop").
            assert (await p.sim(fault="fieldbus lost"))["result"] == "OK"
            s = await p.state("ERROR_LOCKOUT")
            assert "ESTOP_PRESSED" in s["alarms"], s
            await both(True, "still pressed in ERROR_LOCKOUT")
            assert (await p.sim(set={"estop.a": 1, "estop.b": 1}))["result"] == "OK"
            await p.status(lambda s: "ESTOP_PRESSED" not in s["alarms"], what="released")
            await both(False, "released in ERROR_LOCKOUT")
            assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
            s = await p.status(lambda s: "ESTOP_PRESSED" in s["alarms"], what="pressed again")
            assert s["state"] == "ERROR_LOCKOUT", s
            await both(True, "pressed in ERROR_LOCKOUT")
        await p.close()
    run(main())


def test_protective_stop_counts_only_an_enabled_guard(opc):
    """40010-1: if Enabled is FALSE, Active is FALSE, and ProtectiveStop counts enabled functions
    only. The latched PROTECTIVE_STOP after the key went to T1 is shown by its alarm condition."""
    async def main():
        p = await booted(opc.cell)
        assert await p.command("reset") == "OK"
        await p.state("IDLE")
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            pstop = await n.safety("ProtectiveStop")
            gate = [await n.get(f"{n.rob}:SafetyStates", f"{n.own}:SafetyState", f"{n.rob}:ProtectiveStopFunctions",
                                f"{n.own}:Gate", f"{n.rob}:{v}") for v in ("Enabled", "Active")]

            async def reads(enabled, gate_active, protective_stop, what):
                for node, value in ((gate[0], enabled), (gate[1], gate_active), (pstop, protective_stop)):
                    await wait_value(node, lambda dv, v=value: dv.StatusCode.is_good() and dv.Value.Value is v,
                                     what=f"{what}: {value}")

            await reads(True, False, False, "AUTO, guard closed")
            assert await p.command("servo_on") == "OK"
            await p.state("OPERATIONAL", "AUTO_IDLE")
            assert (await p.sim(set={"gate": "open"}))["result"] == "OK"
            s = await p.status(lambda s: "PROTECTIVE_STOP" in s["alarms"], what="PROTECTIVE_STOP")
            await reads(True, True, True, "guard opened in AUTO")
            assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
            s = await p.status(lambda s: s["mode"] == "T1", what="mode T1")
            assert "PROTECTIVE_STOP" in s["alarms"], "still latched: the key does not reset it"
            await reads(False, False, False, "key to T1, the stop latched")
            condition = await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:PROTECTIVE_STOP")
            assert await (await condition.get_child(["0:ActiveState", "0:Id"])).read_value() is True
        await p.close()
    run(main())


def test_a_subscription_sees_emergency_stop_promptly_after_a_press(opc):
    """Each of three sim E-stop presses is notified to a subscription on EmergencyStop, and its
    release after the reset too; within ESTOP_NOTIFY_MARGIN_S (the 200 ms goal is the bench's)."""
    async def main():
        p = await booted(opc.cell)
        assert await p.command("reset") == "OK"
        await p.state("IDLE")
        seen = asyncio.Queue()

        class Handler:
            def datachange_notification(self, node, val, data):
                seen.put_nowait((time.monotonic(), val))

        async with client(opc.url) as c:
            n = await Nodes.of(c)
            estop = await n.estop_node()
            await wait_value(estop, lambda dv: dv.Value.Value is False, what="EmergencyStop false after reset")
            sub = await c.create_subscription(ua.CreateSubscriptionParameters(RequestedPublishingInterval=20,
                                                                              RequestedMaxKeepAliveCount=100,
                                                                              RequestedLifetimeCount=1000),
                                              Handler())
            await sub.subscribe_data_change(estop, sampling_interval=0)
            t, v = await asyncio.wait_for(seen.get(), 5)
            assert v is False
            delays = []
            for _ in range(3):
                pressed_at = time.monotonic()
                assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
                t, v = await asyncio.wait_for(seen.get(), 5)
                assert v is True
                delays.append(t - pressed_at)
                assert (await p.sim(set={"estop.a": 1, "estop.b": 1}))["result"] == "OK"
                await p.state("ESTOP_RESET_NEEDED")
                assert await p.command("reset") == "OK"
                t, v = await asyncio.wait_for(seen.get(), 5)
                assert v is False
            print(f"E-stop press to OPC UA notification: {[round(d * 1000, 1) for d in delays]} ms "
                  "(the 200 ms goal: bench/opcua_estop.py)")
            assert max(delays) < ESTOP_NOTIFY_MARGIN_S, delays
            await sub.delete()
        await p.close()
    run(main())


def test_key_switch_modes_show_in_operational_mode(opc):
    async def main():
        p = await booted(opc.cell)
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            mode = await n.safety("OperationalMode")
            for key, value in (("T1", 1), ("T2", 2), ("AUTO", 3)):  # OperationalModeEnumeration
                assert (await p.sim(set={"mode": key}))["result"] == "OK"
                await wait_value(mode, lambda dv, v=value: dv.Value.Value == v, what=f"OperationalMode {value}")
                assert await (await n.own_var("mode")).read_value() == key
        await p.close()
    run(main())


def test_safe_limits_show_checksum_validated_and_reduced_mode(opc):
    """SPEC §10 beside the 40010-1 SafetyState: what the status `safety` object says, read-only."""
    async def main():
        p = await booted(opc.cell)
        async with client(opc.url) as c:
            n = await Nodes.of(c)

            async def var(name):
                return await n.get(f"{n.rob}:SafetyStates", f"{n.own}:SafetyState", f"{n.own}:SafeLimits",
                                   f"{n.own}:{name}")
            st = get_json(opc.cell.port, "/api/status")["safety"]
            assert st["validated"] is True, "the built-in configuration"
            await wait_value(await var("checksum"), lambda dv: dv.Value.Value == st["checksum"], what="the checksum")
            assert await (await var("validated")).read_value() is True
            assert await (await var("speed_limit")).read_value() == st["speed_limit"]
            assert await (await var("reduced")).read_value() is False
            assert (await p.sim(set={"reduced": "reduced"}))["result"] == "OK"
            await wait_value(await var("reduced"), lambda dv: dv.Value.Value is True, what="reduced mode")
            await wait_value(await var("reduced_by"), lambda dv: dv.Value.Value == ["input"], what="reduced_by input")
            with pytest.raises(ua.UaStatusCodeError) as e:
                await (await var("validated")).write_value(ua.DataValue(ua.Variant(False, ua.VariantType.Boolean)))
            assert e.value.code == ua.StatusCodes.BadNotWritable
            assert (await p.sim(set={"reduced": "normal"}))["result"] == "OK"
            await wait_value(await var("reduced"), lambda dv: dv.Value.Value is False, what="normal speed")
        await p.close()
    run(main())


def test_collaborative_variables_fields_ssm_and_pfl(tmp_path):
    """SPEC §11 beside SafeLimits: the fields, the separation and v_allowed while SSM acts, pfl
    and the contact force with its F_qs, as the status `safety` object says; no data (Good, a
    Null value) where the status has null. SPEC §12 there too: the brake test's running flag
    while it runs, then its result; due in no data (the built-in configuration requires none)."""
    # The built-in configuration: no collaborative operation.
    tmp_path.joinpath("plain").mkdir()
    opc = OpcCell(tmp_path / "plain")
    try:
        async def plain():
            p = await booted(opc.cell)
            async with client(opc.url) as c:
                n = await Nodes.of(c)

                async def var(name):
                    return await n.get(f"{n.rob}:SafetyStates", f"{n.own}:SafetyState", f"{n.own}:SafeLimits",
                                       f"{n.own}:{name}")
                await wait_value(await var("field_outer"), lambda dv: dv.Value.Value == "clear", what="outer clear")
                assert await (await var("field_inner")).read_value() == "clear"
                assert await (await var("pfl")).read_value() is False
                for name in ("separation_mm", "v_allowed", "contact_force", "contact_force_limit", "BrakeTestDueInHours"):
                    dv = await (await var(name)).read_data_value(raise_on_bad_status=False)
                    assert dv.StatusCode.value == ua.StatusCodes.GoodNoData and dv.Value.Value is None, (name, dv)
                assert await (await var("BrakeTestLastResult")).read_value() == "none"
                assert await (await var("BrakeTestRunning")).read_value() is False
                await to_t1_manual_idle(p)
                assert await p.command("brake_test") == "OK"
                await wait_value(await var("BrakeTestRunning"), lambda dv: dv.Value.Value is True, what="brake test running")
                await wait_value(await var("BrakeTestLastResult"), lambda dv: dv.Value.Value == "passed",
                                 what="brake test passed", timeout=15.0)
                await wait_value(await var("BrakeTestRunning"), lambda dv: dv.Value.Value is False, what="brake test over")
                dv = await (await var("BrakeTestDueInHours")).read_data_value(raise_on_bad_status=False)
                assert dv.StatusCode.value == ua.StatusCodes.GoodNoData, "none required by the built-in configuration"
            await p.close()
        run(plain())
    finally:
        assert opc.cell.stop() == 0, opc.cell.output()

    tmp_path.joinpath("collab").mkdir()
    opc = OpcCell(tmp_path / "collab", ["--safety", str(ROOT / "examples" / "safety" / "collaborative.json")])
    try:
        async def collab():
            p = await booted(opc.cell)
            async with client(opc.url) as c:
                n = await Nodes.of(c)

                async def var(name):
                    return await n.get(f"{n.rob}:SafetyStates", f"{n.own}:SafetyState", f"{n.own}:SafeLimits",
                                       f"{n.own}:{name}")
                # AUTO (the key's start position), no sensor reading: SSM acts and holds.
                await wait_value(await var("v_allowed"), lambda dv: dv.Value.Value == 0.0, what="v_allowed 0")
                assert await (await var("separation_mm")).read_value() == 0.0
                assert await (await var("pfl")).read_value() is True
                assert await (await var("contact_force")).read_value() == 0.0, "power off: no estimate"
                assert await (await var("contact_force_limit")).read_value() == 140.0, "hand: F_qs 140 N"
                assert (await p.sim(set={"separation_mm": 800}))["result"] == "OK"
                await wait_value(await var("separation_mm"), lambda dv: dv.Value.Value == 800.0, what="separation 800")
                # collaborative.md's worked example: 344.8 mm/s at 800 mm.
                await wait_value(await var("v_allowed"), lambda dv: dv.Value.Value == 344.8, what="v_allowed 344.8")
                assert (await p.sim(set={"field.inner": "interrupted"}))["result"] == "OK"
                await wait_value(await var("field_inner"), lambda dv: dv.Value.Value == "interrupted", what="inner field")
                assert await (await var("field_outer")).read_value() == "clear"
                with pytest.raises(ua.UaStatusCodeError) as e:
                    await (await var("pfl")).write_value(ua.DataValue(ua.Variant(False, ua.VariantType.Boolean)))
                assert e.value.code == ua.StatusCodes.BadNotWritable
            await p.close()
        run(collab())
    finally:
        assert opc.cell.stop() == 0, opc.cell.output()


def test_start_answers_gate_open_in_auto_and_not_control_owner_in_t1(opc):
    async def main():
        p = await booted(opc.cell)
        assert await p.command("reset") == "OK"
        await p.state("IDLE")
        async with client(opc.url, user=True) as c:
            n = await Nodes.of(c)
            tc = await n.task_control()
            m = {name: await tc.get_child([f"{n.own}:{name}"]) for name in ("Start", "Stop", "Pause", "Resume")}
            assert (await p.sim(set={"gate": "open"}))["result"] == "OK"
            await p.status(lambda s: s["state"] == "IDLE")
            assert await call(c, tc, m["Start"]) == ("BadInvalidState", ["GATE_OPEN"])
            # Bad arguments: the methods take none; nothing reaches the gateway.
            assert await call(c, tc, m["Start"], "demo") == ("BadInvalidArgument", [])
            assert await call(c, tc, m["Start"], 7, "x") == ("BadInvalidArgument", [])
            assert await call(c, tc, m["Pause"], "x") == ("BadInvalidArgument", [])
            assert (await p.status())["state"] == "IDLE", "refused starts changed nothing"

            assert (await p.sim(set={"gate": "closed", "mode": "T1"}))["result"] == "OK"
            await p.status(lambda s: s["mode"] == "T1", what="mode T1")
            assert await call(c, tc, m["Start"]) == ("BadUserAccessDenied", ["NOT_CONTROL_OWNER"])
            assert await call(c, tc, m["Stop"]) == ("BadUserAccessDenied", ["NOT_CONTROL_OWNER"])

            # In AUTO with the guard closed the plant runs the whole cycle.
            assert (await p.sim(set={"mode": "AUTO"}))["result"] == "OK"
            await p.status(lambda s: s["mode"] == "AUTO" and s["state"] == "IDLE", what="AUTO, IDLE")
            if "MODE_CHANGED" in (await p.status())["alarms"]:
                assert await p.command("reset") == "OK"
            assert await call(c, tc, m["Start"]) == ("Good", ["OK"])
            await p.state("OPERATIONAL", "AUTO_RUNNING")
            execution = await tc.get_child([f"{n.own}:ExecutionState"])
            await wait_value(execution, lambda dv: dv.Value.Value == "Running", what="ExecutionState Running")
            # The arm moves: some axis reports a speed, consistent with its position changing.
            axes = [await n.get(f"{n.rob}:MotionDevices", f"{n.own}:Robot", f"{n.rob}:Axes", f"{n.own}:Axis{i}",
                                f"{n.di}:ParameterSet") for i in range(1, 7)]
            speeds = [await a.get_child([f"{n.rob}:ActualSpeed"]) for a in axes]
            positions = [await a.get_child([f"{n.rob}:ActualPosition"]) for a in axes]
            before = [await p_.read_value() for p_ in positions]
            deadline = time.monotonic() + 5
            while max([abs(await v.read_value()) for v in speeds]) <= 0.5:
                assert time.monotonic() < deadline, "no axis reports a speed while the program runs"
                await asyncio.sleep(0.05)
            while [await p_.read_value() for p_ in positions] == before:
                assert time.monotonic() < deadline, "positions do not follow the motion"
                await asyncio.sleep(0.05)
            assert await call(c, tc, m["Pause"]) == ("Good", ["OK"])
            await p.state("OPERATIONAL", "AUTO_PAUSED")
            assert await call(c, tc, m["Resume"]) == ("Good", ["OK"])
            await p.state("OPERATIONAL", "AUTO_RUNNING")
            assert await call(c, tc, m["Stop"]) == ("Good", ["OK"])
            await p.state("OPERATIONAL", "AUTO_IDLE")
            assert await call(c, tc, m["Resume"]) == ("BadInvalidState", ["WRONG_STATE"])
        await p.close()
    run(main())


def test_an_alarm_raises_and_clears_an_ac_event_with_its_number(opc):
    async def main():
        p = await booted(opc.cell)
        assert await p.command("reset") == "OK"
        await p.state("IDLE")
        events = asyncio.Queue()

        class Handler:
            def event_notification(self, event):
                events.put_nowait(event)

        async with client(opc.url) as c:
            n = await Nodes.of(c)
            alarm_type = await c.nodes.base_event_type.get_child(
                ["0:ConditionType", "0:AcknowledgeableConditionType", "0:AlarmConditionType",
                 f"{n.own}:SafeStateAlarmType"])
            sub = await c.create_subscription(50, Handler())
            # The filter result the server answers (asyncua keeps only the item's status).
            answered = []
            create = c.uaclient.create_monitored_items

            async def capture(params):
                results = await create(params)
                answered.extend(zip(params.ItemsToCreate, results))
                return results
            c.uaclient.create_monitored_items = capture
            await sub.subscribe_events(c.nodes.server, alarm_type)
            c.uaclient.create_monitored_items = create
            [(request, result)] = answered
            clauses = request.RequestedParameters.Filter.SelectClauses
            codes = result.FilterResult.SelectClauseResults
            # OPC 10000-9 §5.5.2: ConditionId is the clause (ConditionType, empty path, NodeId).
            condition_id = [i for i, op in enumerate(clauses) if op.AttributeId == ua.AttributeIds.NodeId
                            and not op.BrowsePath and op.TypeDefinitionId == ua.NodeId(ua.ObjectIds.ConditionType)]
            assert len(condition_id) == 1, clauses
            assert len(codes) == len(clauses), codes
            bad = [(clauses[i].BrowsePath, code.name) for i, code in enumerate(codes) if not code.is_good()]
            assert bad == [], f"select clauses not Good in the event filter result: {bad}"
            assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
            await p.state("ESTOP_ACTIVE")
            active = wait_until(lambda: [a for a in get_json(opc.cell.port, "/api/alarms")
                                         if a["name"] == "ESTOP_PRESSED"], 5, "ESTOP_PRESSED in /api/alarms")[0]

            async def next_event(pred, what):
                deadline = time.monotonic() + 5
                while True:
                    e = await asyncio.wait_for(events.get(), max(0.1, deadline - time.monotonic()))
                    if pred(e):
                        return e
                    assert time.monotonic() < deadline, what

            raised = await next_event(lambda e: e.AlarmName == "ESTOP_PRESSED" and e.ActiveState.Text == "Active",
                                      "the ESTOP_PRESSED event")
            assert raised.AlarmNumber == active["number"]
            assert str(active["number"]) in raised.Message.Text and active["text"] in raised.Message.Text
            assert raised.Severity >= 100 and raised.ConditionName == "ESTOP_PRESSED"
            condition = await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:ESTOP_PRESSED")
            assert raised.NodeId == condition.nodeid, "the ConditionId clause delivers the condition's NodeId"
            assert raised.SourceName == "MotionDeviceSystem", raised.SourceName  # the text, no "1:"
            assert raised.SourceNode == (await n.get()).nodeid
            names = await (await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:names")).read_value()
            assert "ESTOP_PRESSED" in names
            numbers = await (await n.get(f"{n.own}:SafeState", f"{n.own}:Alarms", f"{n.own}:numbers")).read_value()
            assert active["number"] in numbers
            # Acknowledging is a method too: an anonymous client may not.
            ack = await c.nodes.base_event_type.get_child(["0:ConditionType", "0:AcknowledgeableConditionType",
                                                          "0:Acknowledge"])
            req = ua.CallMethodRequest()
            req.ObjectId, req.MethodId = condition.nodeid, ack.nodeid
            req.InputArguments = [ua.Variant(raised.EventId, ua.VariantType.ByteString),
                                  ua.Variant(ua.LocalizedText("seen"), ua.VariantType.LocalizedText)]
            [res] = await c.uaclient.call([req])
            assert res.StatusCode.name == "BadUserAccessDenied", res.StatusCode
            assert (await p.sim(set={"estop.a": 1, "estop.b": 1}))["result"] == "OK"
            cleared = await next_event(lambda e: e.AlarmName == "ESTOP_PRESSED" and e.ActiveState.Text == "Inactive",
                                       "the ESTOP_PRESSED cleared event")
            assert cleared.AlarmNumber == active["number"]
            await sub.delete()
        await p.close()
    run(main())


def test_killing_the_gateway_turns_values_bad_and_they_recover(opc):
    async def main():
        async with client(opc.url) as c:
            n = await Nodes.of(c)
            nodes = [await n.estop_node(), await n.own_var("state"), await n.safety("OperationalMode"),
                     await n.get(f"{n.rob}:MotionDevices", f"{n.own}:Robot", f"{n.rob}:Axes", f"{n.own}:Axis1",
                                 f"{n.di}:ParameterSet", f"{n.rob}:ActualPosition")]
            for node in nodes:
                assert (await node.read_data_value()).StatusCode.is_good()
            gw = get_json(opc.cell.port, "/api/status")["gateway_pid"]
            os.kill(gw, signal.SIGKILL)
            for node in nodes:
                dv = await wait_value(node, lambda dv: not dv.StatusCode.is_good(), what="a bad value")
                assert dv.StatusCode.value == ua.StatusCodes.BadCommunicationError, dv
            wait_until(lambda: (s := try_status(opc.cell.port)) and s.get("gateway_pid") not in (None, gw), 15,
                       "the gateway to come back")
            for node in nodes:
                await wait_value(node, lambda dv: dv.StatusCode.is_good(), timeout=15, what="a good value again")
            assert await nodes[1].read_value() == get_json(opc.cell.port, "/api/status")["state"]
    run(main())


def adapter(tmp_path, *args):
    return subprocess.Popen(["node", str(ADAPTER), "--gateway", "127.0.0.1:9", "--pki", str(tmp_path / "pki"),
                             *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_beyond_loopback_refuses_to_start_without_users_and_refuses_anonymous(tmp_path):
    port = free_port()
    a = adapter(tmp_path, "--bind", "0.0.0.0", "--port", str(port))
    out, _ = a.communicate(timeout=30)
    assert a.returncode == 2, out
    assert "refusing to listen on 0.0.0.0 without --users-file" in out

    bad = adapter(tmp_path, "--port", "70000")
    out, _ = bad.communicate(timeout=30)
    assert bad.returncode == 2 and "--port" in out, out

    users = users_file(tmp_path / "users")
    unknown = run(make_client_certificate(tmp_path, "stranger"))
    known = run(make_client_certificate(tmp_path, "plc"))
    trust(tmp_path / "pki", known[1])
    a = adapter(tmp_path, "--bind", "0.0.0.0", "--port", str(port), "--users-file", str(users))
    try:
        async def main():
            url = f"opc.tcp://127.0.0.1:{port}"
            deadline = time.monotonic() + 30
            while True:
                try:  # GetEndpoints is answered on an unsecured channel without a session
                    endpoints = await UaClient(url, timeout=2).connect_and_get_server_endpoints()
                    break
                except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError):
                    assert a.poll() is None and time.monotonic() < deadline, "adapter did not serve"
                    await asyncio.sleep(0.3)
            # Only Basic256Sha256 with Sign&Encrypt, and no anonymous token.
            assert endpoints
            for e in endpoints:
                assert e.SecurityPolicyUri == "http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256", e
                assert e.SecurityMode == ua.MessageSecurityMode.SignAndEncrypt
                assert ua.UserTokenType.Anonymous not in [t.TokenType for t in e.UserIdentityTokens]
        run(main())

        async def anonymous():
            async with UaClient(f"opc.tcp://127.0.0.1:{port}", timeout=5):
                pass
        with pytest.raises(ua.UaStatusCodeError) as e:
            asyncio.run(asyncio.wait_for(anonymous(), 30))
        assert e.value.code in (ua.StatusCodes.BadSecurityModeRejected, ua.StatusCodes.BadIdentityTokenInvalid,
                                ua.StatusCodes.BadSecurityPolicyRejected), e.value
        run(unknown_certificate_refused_trusted_one_served(tmp_path, port, unknown, known))
    finally:
        a.send_signal(signal.SIGTERM)
        a.wait(timeout=10)


async def endpoints_of(a, port):
    """The endpoints of a lone adapter, once it serves (GetEndpoints needs no session)."""
    url = f"opc.tcp://127.0.0.1:{port}"
    deadline = time.monotonic() + 30
    while True:
        try:
            return await UaClient(url, timeout=2).connect_and_get_server_endpoints()
        except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError):
            assert a.poll() is None and time.monotonic() < deadline, "adapter did not serve"
            await asyncio.sleep(0.3)


@pytest.fixture(scope="module")
def lone_adapter(tmp_path_factory):
    """The adapter on loopback without a gateway (its address space is built all the same)."""
    tmp = tmp_path_factory.mktemp("lone")
    port = free_port()
    a = adapter(tmp, "--port", str(port), "--users-file", str(users_file(tmp / "users")))
    try:
        run(endpoints_of(a, port))
        yield tmp, port
    finally:
        a.send_signal(signal.SIGTERM)
        a.wait(timeout=10)


def test_x509_user_tokens_are_not_offered_and_an_unknown_certificate_cannot_log_in(lone_adapter):
    """docs/opcua.md: users are name and password; X509 user identity is not implemented, so
    the token type is not offered and a login with a self-signed certificate is refused."""
    tmp, port = lone_adapter
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

    async def main():
        endpoints = await UaClient(f"opc.tcp://127.0.0.1:{port}", timeout=5).connect_and_get_server_endpoints()
        offered = {(e.SecurityMode.name, t.TokenType.name) for e in endpoints for t in e.UserIdentityTokens}
        assert ("SignAndEncrypt", "UserName") in offered, offered
        assert not [o for o in offered if o[1] == "Certificate"], offered
        channel = await make_client_certificate(tmp, "channel")  # loopback: accepted for the channel
        user_key, user_cert, _ = await make_client_certificate(tmp, "x509-user")
        c = UaClient(f"opc.tcp://127.0.0.1:{port}", timeout=5)
        c.application_uri = channel[2]
        await c.set_security(SecurityPolicyBasic256Sha256, str(channel[1]), str(channel[0]),
                             mode=ua.MessageSecurityMode.SignAndEncrypt)
        await c.load_client_certificate(str(user_cert))
        await c.load_private_key(user_key)
        with pytest.raises(ua.UaStatusCodeError) as e:
            async with c:
                pass
        assert e.value.code in (ua.StatusCodes.BadIdentityTokenInvalid, ua.StatusCodes.BadIdentityTokenRejected), \
            e.value
    run(main())


def test_the_namespace_versions_served_are_the_ones_the_docs_name(lone_adapter):
    """docs/opcua.md names the nodeset versions; the server's Namespaces object says which
    ones are loaded (issue 24: DI 1.05.0 served, 1.04 documented)."""
    _, port = lone_adapter
    docs = (ROOT / "docs" / "opcua.md").read_text()

    async def main():
        async with client(f"opc.tcp://127.0.0.1:{port}") as c:
            namespaces = await c.nodes.server.get_child(["0:Namespaces"])
            versions = {}
            for ns in await namespaces.get_children():
                uri = (await ns.read_browse_name()).Name
                versions[uri] = await (await ns.get_child(["0:NamespaceVersion"])).read_value()
        for name, uri in (("OPC UA", "http://opcfoundation.org/UA/"), ("DI", DI), ("IA", "http://opcfoundation.org/UA/IA/"),
                          ("Robotics", ROBOTICS)):
            assert f"{name} {versions[uri]}" in docs.replace("**", ""), (name, versions[uri])
    run(main())


async def make_client_certificate(tmp_path, name):
    """(key, DER certificate, application URI) of a new self-signed client certificate."""
    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from cryptography.x509.oid import ExtendedKeyUsageOID
    key, cert = tmp_path / f"{name}-key.pem", tmp_path / f"{name}-cert.der"
    uri = f"urn:safestate:test:{name}"
    await setup_self_signed_certificate(key, cert, uri, "localhost", [ExtendedKeyUsageOID.CLIENT_AUTH],
                                        {"commonName": f"safestate test {name}"})
    return key, cert, uri


def trust(pki, cert):
    """What an administrator does before the server starts: the client's certificate into
    pki/trusted/certs (PEM)."""
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding
    trusted = pki / "trusted" / "certs"
    trusted.mkdir(parents=True, exist_ok=True)
    pem = x509.load_der_x509_certificate(cert.read_bytes()).public_bytes(Encoding.PEM)
    (trusted / (cert.stem + ".pem")).write_bytes(pem)


async def secure_call(port, key, cert, uri):
    """Basic256Sha256 Sign&Encrypt with the test user: (EmergencyStop's status, Start's answer)."""
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
    c = client(f"opc.tcp://127.0.0.1:{port}", user=True)
    c.application_uri = uri
    await c.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key), mode=ua.MessageSecurityMode.SignAndEncrypt)
    async with c:
        n = await Nodes.of(c)
        dv = await (await n.estop_node()).read_data_value(raise_on_bad_status=False)
        tc = await n.task_control()
        return dv.StatusCode.name, await call(c, tc, await tc.get_child([f"{n.own}:Start"]))


async def unknown_certificate_refused_trusted_one_served(tmp_path, port, unknown, known):
    """Beyond loopback a client certificate must have been trusted by an administrator."""
    with pytest.raises(Exception):
        await asyncio.wait_for(secure_call(port, *unknown), 30)
    rejected = list((tmp_path / "pki" / "rejected").glob("*"))
    assert rejected, "the refused certificate waits in pki/rejected for an administrator"
    # Trusted and authenticated: reads work (bad values: this adapter has no gateway, never a
    # stale good) and the call goes through to the absent gateway.
    assert await asyncio.wait_for(secure_call(port, *known), 30) == \
        ("BadCommunicationError", ("BadCommunicationError", ["GATEWAY_UNAVAILABLE"]))


def test_a_busy_opcua_port_harms_nothing_and_the_adapter_comes_when_it_is_free(tmp_path):
    """Decision (docs/opcua.md): an adapter that cannot bind exits and `safestate run` retries
    it with back-off; the core and the gateway carry on."""
    import socket
    blocker = socket.socket()
    blocker.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    blocker.bind(("127.0.0.1", 0))
    blocker.listen()
    port = blocker.getsockname()[1]
    cell = SafeState(tmp_path, args=["--opcua-port", str(port)])
    try:
        wait_until(lambda: f"port {port} on 127.0.0.1 is in use" in cell.output(), 20, "the adapter to say the port is busy")
        wait_until(lambda: "the OPC UA adapter exited" in cell.output(), 10, "safestate run to notice")
        assert try_status(cell.port)["state"] == "ESTOP_RESET_NEEDED", "the gateway serves on"
        blocker.close()

        async def served():
            deadline = time.monotonic() + 45
            while True:
                try:
                    async with UaClient(f"opc.tcp://127.0.0.1:{port}", timeout=2) as c:
                        n = await Nodes.of(c)
                        dv = await (await n.estop_node()).read_data_value(raise_on_bad_status=False)
                        if dv.StatusCode.is_good():
                            return
                except (OSError, asyncio.TimeoutError, ua.UaError, ConnectionError):
                    pass
                assert time.monotonic() < deadline, cell.output()
                await asyncio.sleep(0.5)
        run(served())
    finally:
        blocker.close()
        assert cell.stop() == 0, cell.output()


def test_safestate_run_without_the_adapter_built_says_so_and_serves_on(tmp_path):
    cell = SafeState(tmp_path, args=["--opcua-port", str(free_port()), "--opcua-main", str(tmp_path / "nowhere.js")])
    try:
        wait_until(lambda: "the OPC UA adapter is not built" in cell.output(), 10, "the message")
        assert try_status(cell.port) is not None
    finally:
        assert cell.stop() == 0, cell.output()


def test_a_killed_adapter_is_restarted(opc):
    pids = subprocess.run(["pgrep", "-P", str(opc.cell.proc.pid), "-f", "adapters/opcua/dist/main.js"],
                          capture_output=True, text=True).stdout.split()
    assert len(pids) == 1, pids
    os.kill(int(pids[0]), signal.SIGKILL)
    wait_until(lambda: "the OPC UA adapter exited (signal 9)" in opc.cell.output(), 10, "safestate run to notice")
    run(opc.wait_served())
    again = subprocess.run(["pgrep", "-P", str(opc.cell.proc.pid), "-f", "adapters/opcua/dist/main.js"],
                           capture_output=True, text=True).stdout.split()
    assert len(again) == 1 and again != pids, again
    assert try_status(opc.cell.port) is not None, "the gateway never noticed"

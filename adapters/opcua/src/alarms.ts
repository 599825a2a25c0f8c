// SafeState alarms as OPC UA Alarms & Conditions (OPC 10000-9): one condition per alarm
// name, of SafeStateAlarmType (AlarmConditionType plus the SafeState alarm number, remedy
// and severity name), raised when the alarm becomes active and cleared when it goes, so a
// SCADA alarm list follows without polling. The active list itself is also served as plain
// arrays in SafeState's namespace.
import { DataType, LocalizedText, StatusCodes, UAObject, UAObjectType, UAVariable, VariantArrayType } from "node-opcua";
import type { UAAlarmConditionEx } from "node-opcua-address-space";
import { AlarmInfo } from "./gateway_client";
import { Model } from "./model";

// OPC 10000-9 §5.5.2 severity 1..1000; SPEC §7 severities.
const SEVERITY: Record<string, number> = { info: 200, warning: 400, fault: 700, lockout: 900 };

interface Columns {
  names: UAVariable;
  numbers: UAVariable;
  severities: UAVariable;
  texts: UAVariable;
  remedies: UAVariable;
  since: UAVariable;
}

export class Alarms {
  private readonly type: UAObjectType;
  private readonly folder: UAObject;
  private readonly conditions = new Map<string, UAAlarmConditionEx>();
  private readonly active = new Map<string, AlarmInfo>();
  private readonly columns: Columns;

  constructor(private readonly model: Model) {
    const ns = model.ns;
    this.type = ns.addEventType({
      browseName: "SafeStateAlarmType",
      subtypeOf: "AlarmConditionType",
      isAbstract: false,
    }) as unknown as UAObjectType;
    const prop = (browseName: string, dataType: DataType, description: string) =>
      ns.addVariable({ propertyOf: this.type, browseName, dataType, modellingRule: "Mandatory", description });
    prop("AlarmNumber", DataType.UInt32, "SafeState alarm number (docs/alarms.md)");
    prop("AlarmName", DataType.String, "SafeState alarm name (SPEC §7)");
    prop("AlarmSeverity", DataType.String, "info, warning, fault or lockout");
    prop("Remedy", DataType.String, "what to do about it");
    this.folder = ns.addObject({ browseName: "Alarms", componentOf: model.safeState });
    const column = (browseName: string, dataType: DataType, description: string) =>
      ns.addVariable({ browseName, componentOf: this.folder, dataType, valueRank: 1, arrayDimensions: [0], description });
    this.columns = {
      names: column("names", DataType.String, "active alarm names"),
      numbers: column("numbers", DataType.UInt32, "their numbers"),
      severities: column("severities", DataType.String, "their severities"),
      texts: column("texts", DataType.String, "their texts"),
      remedies: column("remedies", DataType.String, "their remedies"),
      since: column("since", DataType.Double, "core cycle at which each became active"),
    };
    this.markBad();
  }

  // Reconcile the conditions with the gateway's active alarm list (/api/alarms).
  sync(list: AlarmInfo[]): void {
    const now = new Map(list.map((a) => [a.name, a]));
    for (const [name] of this.active) {
      if (!now.has(name)) {
        this.clear(name);
      }
    }
    for (const a of list) {
      if (!this.active.has(a.name)) {
        this.raise(a);
      }
    }
    this.publishColumns(list);
  }

  markBad(): void {
    for (const v of Object.values(this.columns)) {
      v.setValueFromSource({ dataType: DataType.Null }, StatusCodes.BadCommunicationError);
    }
  }

  private publishColumns(list: AlarmInfo[]): void {
    const set = (v: UAVariable, dataType: DataType, value: unknown[]) =>
      v.setValueFromSource({ dataType, arrayType: VariantArrayType.Array, value }, StatusCodes.Good);
    set(this.columns.names, DataType.String, list.map((a) => a.name));
    set(this.columns.numbers, DataType.UInt32, list.map((a) => a.number));
    set(this.columns.severities, DataType.String, list.map((a) => a.severity));
    set(this.columns.texts, DataType.String, list.map((a) => a.text));
    set(this.columns.remedies, DataType.String, list.map((a) => a.remedy));
    set(this.columns.since, DataType.Double, list.map((a) => a.since ?? 0));
  }

  private condition(name: string): UAAlarmConditionEx {
    let c = this.conditions.get(name);
    if (c === undefined) {
      c = this.model.ns.instantiateAlarmCondition(this.type, {
        browseName: name,
        componentOf: this.folder,
        conditionSource: this.model.mds,
        conditionName: name,
        inputNode: this.model.safeState.getChildByName("state") as UAVariable,
      });
      // SourceName is the source's name as text ("MotionDeviceSystem"); node-opcua sets the
      // qualified browse name ("1:MotionDeviceSystem"), which no client expects there.
      c.setSourceName(this.model.mds.browseName.name ?? "");
      this.conditions.set(name, c);
    }
    return c;
  }

  private setProperty(c: UAAlarmConditionEx, name: string, dataType: DataType, value: unknown): void {
    const v = c.getChildByName(name, this.model.ns.index) as UAVariable | null;
    v?.setValueFromSource({ dataType, value });
  }

  private raise(a: AlarmInfo): void {
    this.active.set(a.name, a);
    const c = this.condition(a.name);
    this.setProperty(c, "AlarmNumber", DataType.UInt32, a.number);
    this.setProperty(c, "AlarmName", DataType.String, a.name);
    this.setProperty(c, "AlarmSeverity", DataType.String, a.severity);
    this.setProperty(c, "Remedy", DataType.String, a.remedy);
    const detail = a.detail ? ` (${a.detail})` : "";
    c.activeState.setValue(true);
    c.ackedState.setValue(false);
    c.raiseNewCondition({
      message: new LocalizedText({ text: `${a.number} ${a.name}: ${a.text}${detail}`, locale: "en" }),
      severity: SEVERITY[a.severity] ?? 500,
      retain: true,
      quality: StatusCodes.Good,
    });
  }

  private clear(name: string): void {
    const a = this.active.get(name);
    this.active.delete(name);
    const c = this.conditions.get(name);
    if (c === undefined || a === undefined) {
      return;
    }
    c.activeState.setValue(false);
    c.ackedState.setValue(true);
    c.raiseNewCondition({
      message: new LocalizedText({ text: `${a.number} ${a.name} cleared`, locale: "en" }),
      severity: SEVERITY[a.severity] ?? 500,
      retain: false,
      quality: StatusCodes.Good,
    });
  }
}

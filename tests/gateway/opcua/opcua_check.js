// An independent OPC UA client (node-opcua) against the gateway's OPC UA front, for
// opcua_gateway_test.sh. Commands:
//   node opcua_check.js check ENDPOINT HTTP_URL DEVICE
//     browses Objects/GATEWAY/LINE/DEVICE to every parameter /api/devices/DEVICE polls; reads each
//     one's value, DataType, EURange and EngineeringUnits and compares them with the API's; counts
//     a subscription's notifications; writes in range (read back from the device), out of range
//     (Bad_OutOfRange) and to a read-only word (Bad_NotWritable).
//   node opcua_check.js status ENDPOINT NODE_ID STATUS SECONDS
//     reads NODE_ID until its StatusCode is STATUS (Good, BadNoCommunication, ...), or fails after SECONDS.
// Prints one "ok: ..." line a check; exits 1 at the first failure, saying what differed.
"use strict";
const {
  OPCUAClient, AttributeIds, DataType, StatusCodes, ClientSubscription, ClientMonitoredItem, TimestampsToReturn,
  NodeClass,
} = require("node-opcua");

const say = (text) => console.log(`ok: ${text}`);
function fail(text) {
  console.error(`FAIL: ${text}`);
  process.exit(1);
}
function expect(condition, text) {
  if (!condition) fail(text);
  say(text);
}
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

async function connect(endpoint) {
  const client = OPCUAClient.create({ endpointMustExist: false, connectionStrategy: { maxRetry: 3, initialDelay: 200 } });
  await client.connect(endpoint);
  const session = await client.createSession();
  return { client, session };
}

async function childrenOf(session, nodeId) {
  const result = await session.browse({ nodeId, resultMask: 63, nodeClassMask: 0, includeSubtypes: true,
                                        referenceTypeId: "HierarchicalReferences", browseDirection: 0 });
  if (!result.statusCode.isGood()) fail(`browse ${nodeId}: ${result.statusCode.toString()}`);
  return result.references;
}

async function childNamed(session, nodeId, name) {
  const found = (await childrenOf(session, nodeId)).find((reference) => reference.browseName.name === name);
  if (!found) fail(`no ${name} under ${nodeId}`);
  return found.nodeId.toString();
}

async function readValue(session, nodeId) {
  return session.read({ nodeId, attributeId: AttributeIds.Value });
}

async function property(session, nodeId, name) {
  const found = (await childrenOf(session, nodeId)).find((reference) => reference.browseName.name === name);
  if (!found) return undefined;
  return (await readValue(session, found.nodeId)).value.value;
}

// The API's limit against the EURange's: none is NaN.
function sameLimit(api, range) {
  if (api === null || api === undefined) return Number.isNaN(range);
  return Math.abs(api - range) < 1e-9;
}

async function check(endpoint, httpUrl, deviceName) {
  const api = await (await fetch(`${httpUrl}/api/devices/${deviceName}`)).json();
  const { client, session } = await connect(endpoint);
  // Objects/GATEWAY/LINE/DEVICE, by browse names alone.
  const roots = await childrenOf(session, "ns=0;i=85");
  const gateway = roots.find((reference) => reference.nodeId.namespace === 1);
  if (!gateway) fail("no gateway folder under Objects");
  const line = await childNamed(session, gateway.nodeId, api.line);
  const device = await childNamed(session, line, deviceName);
  expect(device === `ns=1;s=${deviceName}`, `browsed Objects/${gateway.browseName.name}/${api.line}/${deviceName}`);
  const variables = (await childrenOf(session, device)).filter((reference) => reference.nodeClass === NodeClass.Variable);
  const polled = api.parameters.filter((parameter) => parameter.polled);
  for (const parameter of polled) {
    const reference = variables.find((variable) => variable.browseName.name === parameter.name);
    if (!reference) fail(`${parameter.name}: no variable under ${device}`);
    const nodeId = reference.nodeId.toString();
    expect(nodeId === `ns=1;s=${deviceName}.${parameter.name}`, `${parameter.name}: NodeId ${nodeId}`);
    const description = await session.read({ nodeId, attributeId: AttributeIds.Description });
    expect(description.value.value.text === parameter.description, `${parameter.name}: Description is the profile's`);
    const dataType = (await session.read({ nodeId, attributeId: AttributeIds.DataType })).value.value.value;
    const value = await readValue(session, nodeId);
    expect(value.statusCode.isGood(), `${parameter.name}: Good`);
    expect(value.sourceTimestamp instanceof Date && value.sourceTimestamp.getTime() > 0, `${parameter.name}: has a SourceTimestamp`);
    const scaled = parameter.unit !== "" || typeof parameter.decimals === "object" || parameter.decimals > 0;
    if (scaled && typeof parameter.value === "number") {
      expect(dataType === DataType.Double, `${parameter.name}: Double`);
      expect(Math.abs(value.value.value - parameter.value) <= Math.max(1, Math.abs(parameter.value) * 0.05),
             `${parameter.name}: ${value.value.value} as the API's ${parameter.value} (a poll apart)`);
      const range = await property(session, nodeId, "EURange");
      expect(range && sameLimit(parameter.min, range.low) && sameLimit(parameter.max, range.high),
             `${parameter.name}: EURange ${range && range.low}..${range && range.high} as the API's ${parameter.min}..${parameter.max}`);
      const units = await property(session, nodeId, "EngineeringUnits");
      expect(units && units.displayName.text === parameter.unit, `${parameter.name}: EngineeringUnits "${parameter.unit}"`);
      if (parameter.unit === "°C") expect(units.unitId === 4408652, `${parameter.name}: UNECE CEL`);
      if (parameter.unit === "%") expect(units.unitId === 20529, `${parameter.name}: UNECE P1`);
    } else {
      expect([DataType.Int16, DataType.UInt16, DataType.Boolean, DataType.String].includes(dataType),
             `${parameter.name}: a whole word, switch or label (DataType ${DataType[dataType]})`);
    }
  }
  const status = await readValue(session, `ns=1;s=${deviceName}/status`);
  expect(status.value.value === "ok", `${deviceName}/status reads "ok"`);

  // A subscription: the measured value moves with the simulated process, the polls every 300 ms.
  const subscription = ClientSubscription.create(session, {
    requestedPublishingInterval: 100, requestedLifetimeCount: 600, requestedMaxKeepAliveCount: 10,
    maxNotificationsPerPublish: 100, publishingEnabled: true,
  });
  let notifications = 0;
  const item = ClientMonitoredItem.create(subscription, { nodeId: `ns=1;s=${deviceName}.set_point`, attributeId: AttributeIds.Value },
                                          { samplingInterval: 100, discardOldest: true, queueSize: 10 }, TimestampsToReturn.Both);
  item.on("changed", () => { notifications += 1; });
  await new Promise((resolve) => item.once("initialized", resolve));
  await sleep(500);
  expect(notifications === 1, `a subscription's first notification (${notifications})`);

  // Writes: in range, read back from the device through the API; the notification follows.
  const setPoint = `ns=1;s=${deviceName}.set_point`;
  const target = api.parameters.find((parameter) => parameter.name === "set_point").value === 123 ? 124 : 123;
  const written = await session.write({ nodeId: setPoint, attributeId: AttributeIds.Value,
                                        value: { value: { dataType: DataType.Double, value: target } } });
  expect(written.isGood(), `write set_point ${target}: ${written.toString()}`);
  const deadline = Date.now() + 10000;
  for (;;) {
    const now = await (await fetch(`${httpUrl}/api/devices/${deviceName}`)).json();
    if (now.parameters.find((parameter) => parameter.name === "set_point").value === target) break;
    if (Date.now() > deadline) fail(`the device does not hold set_point ${target} 10 s after a Good write`);
    await sleep(100);
  }
  say(`the device holds set_point ${target}`);
  for (const until = Date.now() + 10000; notifications < 2 && Date.now() < until;) await sleep(50);
  expect(notifications >= 2, `the write's new value notified (${notifications} notifications)`);
  const value = await readValue(session, setPoint);
  expect(value.value.value === target, `read back set_point ${value.value.value}`);
  const tooHigh = await session.write({ nodeId: setPoint, attributeId: AttributeIds.Value,
                                        value: { value: { dataType: DataType.Double, value: 99999 } } });
  expect(tooHigh.value === StatusCodes.BadOutOfRange.value, `write set_point 99999: ${tooHigh.toString()}`);
  const readOnly = await session.write({ nodeId: `ns=1;s=${deviceName}.measured_value`, attributeId: AttributeIds.Value,
                                         value: { value: { dataType: DataType.Double, value: 1 } } });
  expect(readOnly.value === StatusCodes.BadNotWritable.value, `write measured_value: ${readOnly.toString()}`);
  await subscription.terminate();
  await session.close();
  await client.disconnect();
}

async function status(endpoint, nodeId, wanted, seconds) {
  const { client, session } = await connect(endpoint);
  const deadline = Date.now() + Number(seconds) * 1000;
  let last;
  for (;;) {
    last = (await readValue(session, nodeId)).statusCode;
    if (last.name === wanted) break;
    if (Date.now() > deadline) fail(`${nodeId}: ${last.toString()} after ${seconds} s, not ${wanted}`);
    await sleep(100);
  }
  say(`${nodeId}: ${last.toString()}`);
  await session.close();
  await client.disconnect();
}

const [command, ...args] = process.argv.slice(2);
const commands = { check, status };
if (!commands[command]) fail(`unknown command ${command} (check or status)`);
commands[command](...args).then(() => process.exit(0), (error) => fail(error.stack || String(error)));

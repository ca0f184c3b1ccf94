// The few values that say how a device is doing: the profile's PV, SP and OUT aliases when the
// API names them, else the parameters whose mnemonic is PV/SP/OUT, else the first values polled.
const KEY_ALIASES = ["PV", "SP", "OUT"];

export function keyParameters(device) {
  const params = device.params;
  const picked = [];
  const aliases = device.aliases || device.detail?.aliases;
  if (aliases && typeof aliases === "object") {
    for (const alias of KEY_ALIASES) {
      const name = aliases[alias];
      if (name && params.has(name) && params.get(name).polled !== false && !picked.some((p) => p.name === name)) picked.push({ label: alias, name });
    }
  }
  if (!picked.length) {
    for (const alias of KEY_ALIASES) {
      for (const [name, entry] of params) {
        if ((entry.mnemonic || "").toUpperCase() === alias && !picked.some((p) => p.name === name)) {
          picked.push({ label: alias, name });
          break;
        }
      }
    }
  }
  if (!picked.length) {
    for (const [name, entry] of params) {
      if (picked.length >= 3) break;
      if (entry.time && (typeof entry.value === "number" || entry.text)) picked.push({ label: entry.mnemonic || "", name });
    }
  }
  return picked;
}

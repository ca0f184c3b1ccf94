// Small pieces the views share with the shell: the theme in force and the token dialog.
import { storedToken } from "./api.js";

export function currentTheme() {
  const chosen = document.documentElement.dataset.theme;
  if (chosen) return chosen;
  return window.matchMedia("(prefers-color-scheme: dark)").matches ? "dark" : "light";
}

export function openTokenDialog() {
  const dialog = document.getElementById("token-dialog");
  const input = document.getElementById("token-input");
  input.value = storedToken();
  if (!dialog.open) dialog.showModal();
  input.focus();
}

// "SSi AC20 · ac20@1 · line plant": what the device is and where it sits.
export function deviceSubtitle(device) {
  const address = device.device ? `${device.device}${device.unit !== undefined && device.unit !== "" ? `@${device.unit}` : ""}` : "";
  return [device.title, address, device.line ? `line ${device.line}` : ""].filter(Boolean).join(" · ");
}

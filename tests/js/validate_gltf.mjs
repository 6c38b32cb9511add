// Validate one GLB/glTF file with the Khronos glTF validator; print its report as JSON on stdout.
// Usage: node validate_gltf.mjs FILE.glb   (exit 0 = report printed, whatever it says)
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");
const file = process.argv[2];
if (!file) {
  console.error("usage: node validate_gltf.mjs FILE.glb");
  process.exit(2);
}
const data = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(data, {
  uri: file,
  maxIssues: 200,
  externalResourceFunction: () => Promise.reject(new Error("external resources are not allowed")),
});
console.log(JSON.stringify(report));

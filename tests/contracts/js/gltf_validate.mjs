// Khronos glTF-Validator on a .glb: prints {errors, warnings, infos, messages} as JSON.
// Usage: node gltf_validate.mjs FILE.glb
import fs from "node:fs";
import validator from "gltf-validator";

const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2])));
console.log(JSON.stringify({ errors: report.issues.numErrors, warnings: report.issues.numWarnings,
  infos: report.issues.numInfos, messages: report.issues.messages.slice(0, 20) }));

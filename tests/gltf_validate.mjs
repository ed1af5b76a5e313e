// Validate glTF / GLB files with the Khronos glTF validator (npm package gltf-validator).
// Usage: node tests/gltf_validate.mjs PREFIX FILE...  (PREFIX: where npm installed it, e.g.
// .ci/node) -> one JSON line per file:
// {"file": ..., "errors": N, "warnings": N, "messages": [...]}
import { createRequire } from "module";
import fs from "fs";
import path from "path";

const [prefix, ...files] = process.argv.slice(2);
const require = createRequire(path.resolve(prefix, "package.json"));
const validator = require("gltf-validator");

for (const file of files) {
  const data = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 100,
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
      fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, bytes) =>
        err ? reject(err.toString()) : resolve(new Uint8Array(bytes)));
    }),
  });
  const issues = report.issues;
  console.log(JSON.stringify({
    file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    messages: issues.messages.filter((m) => m.severity <= 1)
      .map((m) => `${m.code}: ${m.message} (${m.pointer || ""})`),
  }));
}

// Validate one glTF/GLB file with the Khronos glTF Validator; print its JSON report on stdout.
// Usage: NODE_PATH=<prefix>/node_modules node gltf_validate.js FILE
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
const bytes = new Uint8Array(fs.readFileSync(file));
validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 100,
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)),
                    (err, data) => (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
    }),
}).then(
    (report) => { process.stdout.write(JSON.stringify(report)); },
    (error) => { process.stderr.write(String(error) + "\n"); process.exit(2); },
);

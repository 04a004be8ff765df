// Validate glTF files with the Khronos glTF-Validator (npm package gltf-validator) through
// its JavaScript API (validateBytes) and print, per file, the counts of errors, warnings,
// infos and hints, and every error and warning.
//
//   node tests/gltf_validate.mjs VALIDATOR_DIR FILE.glb...
//
// VALIDATOR_DIR is the folder holding node_modules/gltf-validator (scripts/setup.sh puts
// it in .tools/gltf-validator). Exit status: 0 when every file has no error and no
// warning, 1 when one has, 2 on bad usage or a file that cannot be read, 77 when the
// package is missing.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';

const [dir, ...files] = process.argv.slice(2);
if (!dir || files.length === 0) {
	console.error('usage: node gltf_validate.mjs VALIDATOR_DIR FILE.glb...');
	process.exit(2);
}
let validator;
try {
	const require = createRequire(path.resolve(dir, 'package.json'));
	validator = require('gltf-validator');
} catch (e) {
	console.error(`gltf_validate: no gltf-validator package under ${dir} (scripts/setup.sh ` +
	              `installs it): ${e.message}`);
	process.exit(77);
}

let bad = 0;
for (const file of files) {
	let bytes;
	try {
		bytes = new Uint8Array(fs.readFileSync(file));
	} catch (e) {
		console.error(`${file}: cannot read it: ${e.message}`);
		process.exit(2);
	}
	const report = await validator.validateBytes(bytes, { uri: path.basename(file), maxIssues: 0 });
	const n = report.issues;
	console.log(`${file}: validator ${report.validatorVersion}: ${n.numErrors} errors, ` +
	            `${n.numWarnings} warnings, ${n.numInfos} infos, ${n.numHints} hints`);
	for (const m of n.messages) {
		if (m.severity <= 1)
			console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} at ${m.pointer ?? m.offset}: ${m.message}`);
		else
			console.log(`  ${m.severity === 2 ? 'info' : 'hint'} ${m.code} at ${m.pointer ?? m.offset}: ${m.message}`);
	}
	if (n.numErrors > 0 || n.numWarnings > 0)
		bad = 1;
}
process.exit(bad);

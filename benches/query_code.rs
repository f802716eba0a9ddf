//! The CSSM query's code, counted (issue 48, "instructions per tap"): the visibility library
//! compiled to SPIR-V by naga, as wgpu hands it to a Vulkan driver (its default runtime
//! checks: integer division guards, bounded loops), and each function's instructions counted
//! with everything it calls inlined. A tap is one pixel's test of the PCF footprint; a query
//! of one texel's cube map (`cssm_answer_texel`) is four taps and what they share.
//!
//! ```text
//! cargo bench --bench query_code -- [--steps 7] [--baseline OLD_CSSM.wgsl] [--spirv DIR]
//! ```
//!
//! `--spirv DIR` also writes each library's module to `DIR/LABEL.spv` (`spirv-dis` reads it).
//!
//! `--steps` is the search's step count the library is composed with (a file's
//! `CssmGpu::search_steps`: the bit length of its longest run list; 8 for the Cornell box at
//! atlas 128, cube 32). `--baseline` counts an earlier version of `visibility/cssm.wgsl` beside
//! the current one (`git show 82dc5c9:runtime/src/visibility/cssm.wgsl > old.wgsl`: the query
//! before the lean rewrite, whose tap is `cssm_pixel_test`).
//!
//! These are static counts: an instruction in a branch counts whether or not a lane takes it,
//! and a search step counts in full though a short run list skips its body. The kernels'
//! counters (`QueryKernel::counting`) say how many taps and steps a workload executes.

use std::collections::HashMap;

use cssm::runtime::{gpu_types::TYPES_WGSL, shaders::CssmShape, visibility::plain_wgsl};

#[path = "common/mod.rs"]
mod common;

/// SPIR-V opcodes read here.
const OP_NAME: u32 = 5;
const OP_FUNCTION: u32 = 54;
const OP_FUNCTION_END: u32 = 56;
const OP_FUNCTION_CALL: u32 = 57;
/// Integer division and remainder: tens of instructions each on a GPU.
const INTEGER_DIVISIONS: [u32; 5] = [134, 135, 137, 138, 139];

/// One function's own instructions, integer divisions and calls.
#[derive(Default)]
struct Function {
    instructions: u64,
    divisions: u64,
    calls: Vec<u32>,
}

/// Instructions and integer divisions per function of `words` (a SPIR-V module), with every
/// call inlined, by function name.
fn inlined_counts(words: &[u32]) -> HashMap<String, (u64, u64)> {
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut functions: HashMap<u32, Function> = HashMap::new();
    let mut current: Option<u32> = None;
    let mut i = 5; // the header
    while i < words.len() {
        let (count, opcode) = ((words[i] >> 16) as usize, words[i] & 0xFFFF);
        let operands = &words[i + 1..i + count.max(1)];
        match opcode {
            OP_NAME => {
                let bytes: Vec<u8> = operands[1..]
                    .iter()
                    .flat_map(|w| w.to_le_bytes())
                    .take_while(|&b| b != 0)
                    .collect();
                names.insert(operands[0], String::from_utf8_lossy(&bytes).into_owned());
            }
            OP_FUNCTION => {
                current = Some(operands[1]);
                functions.insert(operands[1], Function::default());
            }
            OP_FUNCTION_END => current = None,
            _ => {
                if let Some(f) = current.and_then(|id| functions.get_mut(&id)) {
                    f.instructions += 1;
                    if INTEGER_DIVISIONS.contains(&opcode) {
                        f.divisions += 1;
                    }
                    if opcode == OP_FUNCTION_CALL {
                        f.calls.push(operands[2]);
                    }
                }
            }
        }
        i += count.max(1);
    }
    fn inline(id: u32, functions: &HashMap<u32, Function>) -> (u64, u64) {
        let f = &functions[&id];
        f.calls
            .iter()
            .fold((f.instructions, f.divisions), |(n, d), &c| {
                let (cn, cd) = inline(c, functions);
                (n + cn, d + cd)
            })
    }
    functions
        .keys()
        .filter_map(|id| Some((names.get(id)?.clone(), inline(*id, &functions))))
        .collect()
}

/// `module` validated and written as SPIR-V, as wgpu compiles it for Vulkan.
fn spirv_of(module: &naga::Module) -> Vec<u32> {
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(module)
    .unwrap_or_else(|e| panic!("{e:?}"));
    let mut options = naga::back::spv::Options::default();
    options.flags |= naga::back::spv::WriterFlags::DEBUG;
    naga::back::spv::write_vec(module, &info, &options, None).expect("SPIR-V")
}

/// The two query kernels as the renderer composes them (naga_oil), the static scene's
/// (`query.wgsl`) and the moving objects' (`moving_query.wgsl`) for 1, 4 and 8 objects with a
/// CSM, each search and per-object step looped or unrolled: the entry point's instructions with
/// every call inlined, as a driver that inlines everything sees them (issue 48, item 5: the
/// moving query's code should not grow with the objects).
fn kernel_rows(steps: u32) {
    println!(
        "\n| kernel | objects with a CSM | search | SPIR-V instructions of `main` (calls inlined) |"
    );
    println!("| --- | ---: | --- | ---: |");
    for search_loop in [false, true] {
        let shape = CssmShape {
            search_steps: steps,
            search_loop,
            ..Default::default()
        };
        let form = if search_loop { "looped" } else { "unrolled" };
        let kernels = [
            (cssm::runtime::visibility::QUERY_SHADER, 0),
            (cssm::runtime::visibility::moving::SHADER, 1),
            (cssm::runtime::visibility::moving::SHADER, 4),
            (cssm::runtime::visibility::moving::SHADER, 8),
        ];
        for (shader, csms) in kernels {
            let module = shader
                .module_for_scene(shape, csms)
                .unwrap_or_else(|e| panic!("{}: {e}", shader.label()));
            let (instructions, _) = inlined_counts(&spirv_of(&module))["main"];
            println!("| {} | {csms} | {form} | {instructions} |", shader.label());
        }
    }
}

/// `library` (the CSSM library's source) composed for `steps` search steps, unrolled, with an
/// entry point that calls the query, compiled to SPIR-V as wgpu compiles it for Vulkan.
fn spirv(library: &str, steps: u32, search_loop: bool) -> Vec<u32> {
    let shape = CssmShape {
        search_steps: steps,
        search_loop,
        ..Default::default()
    };
    let source = plain_wgsl(&[TYPES_WGSL, library], 1, shape)
        + "@group(0) @binding(0) var<storage, read_write> answers: array<f32>;
           @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3u) {
               answers[id.x] = cssm_visibility(id.x, vec3f(0.3), vec3f(f32(id.y)), vec3f(0.0));
           }";
    let module = naga::front::wgsl::parse_str(&source)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
    spirv_of(&module)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let steps = common::parsed(&args, "--steps", 8u32);
    let baseline: Option<String> = args
        .iter()
        .position(|a| a == "--baseline")
        .and_then(|i| args.get(i + 1))
        .map(|path| {
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("--baseline {path}: {e}"))
        });
    let spirv_dir: Option<std::path::PathBuf> = args
        .iter()
        .position(|a| a == "--spirv")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);
    let current = include_str!("../runtime/src/visibility/cssm.wgsl");
    println!(
        "| library | search | function | SPIR-V instructions (calls inlined) | integer divisions |"
    );
    println!("| --- | --- | --- | ---: | ---: |");
    let mut rows = vec![
        ("current", current, steps, false, "cssm_tap"),
        ("current-loop", current, steps, true, "cssm_tap"),
    ];
    if let Some(old) = &baseline {
        // The old library searched 17 steps whatever the file.
        rows.push(("baseline", old.as_str(), 17, false, "cssm_pixel_test"));
    }
    for (label, library, steps, search_loop, tap) in rows {
        let words = spirv(library, steps, search_loop);
        if let Some(dir) = &spirv_dir {
            let path = dir.join(format!("{label}.spv"));
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
        let counts = inlined_counts(&words);
        for function in [tap, "cssm_answer_texel", "cssm_visibility"] {
            let (instructions, divisions) = counts
                .get(function)
                .copied()
                .unwrap_or_else(|| panic!("{label}: no function {function}"));
            let search = if search_loop {
                format!("loop of {steps}")
            } else {
                format!("{steps} unrolled")
            };
            println!("| {label} | {search} | {function} | {instructions} | {divisions} |");
        }
    }
    kernel_rows(steps);
}

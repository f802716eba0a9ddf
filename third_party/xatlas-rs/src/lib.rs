#![allow(unused)]
// Vendored third-party code (see PATCHED.md): not linted as ours.
#![allow(warnings)]

mod bindings;
use bindings::root::xatlas;

use std::ops::Drop;

use crate::bindings::*;

// jb-todo: find a way to call ParameterizeFunc wrapped in a closure

/// Stops xatlas from printing its warnings to standard output (patched in, see PATCHED.md).
pub fn silence_messages() {
    unsafe { xatlas::SetPrint(None, false) }
}

/// Makes a failed allocation inside xatlas end the process as a failed Rust allocation does
/// (`memory allocation of N bytes failed`, then abort) instead of letting xatlas write through
/// the null pointer it does not check (patched in, see PATCHED.md).
pub fn abort_on_failed_allocation() {
    unsafe extern "C" {
        fn realloc(ptr: *mut std::ffi::c_void, size: usize) -> *mut std::ffi::c_void;
    }
    unsafe extern "C" fn checked(ptr: *mut std::ffi::c_void, size: usize) -> *mut std::ffi::c_void {
        let out = unsafe { realloc(ptr, size) };
        if out.is_null() && size != 0 {
            // xatlas asks for 16-byte alignment at most (its own header included).
            let layout = std::alloc::Layout::from_size_align(size, 16)
                .unwrap_or(std::alloc::Layout::new::<u8>());
            std::alloc::handle_alloc_error(layout);
        }
        out
    }
    unsafe { xatlas::SetRealloc(Some(checked)) }
}

#[derive(Debug)]
pub enum IndexFormat {
    Uint16,
    Uint32,
}

impl Default for IndexFormat {
    fn default() -> IndexFormat {
        IndexFormat::Uint16
    }
}

// xatlas makes internal copies of all of these so just passing references to slices is more then enough
#[repr(C)]
#[derive(Debug)]
pub enum ProgressCategory {
    ComputeCharts,
    ParameterizeCharts,
    PackCharts,
    BuildOutputMeshes
}

#[repr(C)]
#[derive(Default, Debug)]
pub struct MeshDecl<'a> {
    pub vertex_count: u32,
    pub vertex_position_data: &'a [u8],
    pub vertex_position_stride: u32,
    pub vertex_normal_data: &'a [u8],
    pub vertex_normal_stride: u32,
    pub vertex_uv_data: &'a [u8],
    pub vertex_uv_stride: u32,
    pub index_count: u32,
    pub index_data: &'a [u8],
    pub index_offset: i32,
    pub index_format: IndexFormat,
    pub face_ignore_data: &'a [bool],
}

#[derive(Debug)]
pub struct ChartOptions {
    pub proxy_fit_metric_weight: f32,
    pub roundness_metric_weight: f32,
    pub straightness_metric_weight: f32,
    pub normal_seam_metric_weight: f32,
    pub texture_seam_metric_weight: f32,
    pub max_chart_area: f32,
    pub max_boundary_length: f32,
    pub max_threshold: f32,
    pub grow_face_count: u32,
    pub max_iterations: u32,
}

impl ChartOptions {
    fn convert(&self) -> xatlas::ChartOptions {
        xatlas::ChartOptions {
            proxyFitMetricWeight: self.proxy_fit_metric_weight,
            roundnessMetricWeight: self.roundness_metric_weight,
            straightnessMetricWeight: self.straightness_metric_weight,
            normalSeamMetricWeight: self.normal_seam_metric_weight,
            textureSeamMetricWeight: self.texture_seam_metric_weight,
            maxChartArea: self.max_chart_area,
            maxBoundaryLength: self.max_boundary_length,
            maxThreshold: self.max_threshold,
            growFaceCount: self.grow_face_count,
            maxIterations: self.max_iterations,
        }
    }
}

impl Default for ChartOptions {
    fn default() -> ChartOptions {
        ChartOptions {
            proxy_fit_metric_weight: 2.0,
            roundness_metric_weight: 0.01,
            straightness_metric_weight: 6.0,
            normal_seam_metric_weight: 4.0,
            texture_seam_metric_weight: 0.5,
            max_chart_area: 0.0,
            max_boundary_length: 0.0,
            max_threshold: 2.0,
            grow_face_count: 32,
            max_iterations: 1,
        }
    }
}

#[derive(Debug)]
pub struct PackOptions {
    pub attempts: i32,
    pub texels_per_unit: f32,
    pub resolution: u32,
    pub max_chart_size: u32,
    pub block_align: bool,
    pub conservative: bool,
    pub padding: u32,
}

impl PackOptions {
    fn convert(&self) -> xatlas::PackOptions {
        xatlas::PackOptions {
            attempts: self.attempts,
            texelsPerUnit: self.texels_per_unit,
            resolution: self.resolution,
            maxChartSize: self.max_chart_size,
            blockAlign: self.block_align,
            conservative: self.conservative,
            padding: self.padding,
        }
    }
}

impl Default for PackOptions {
    fn default() -> PackOptions {
        PackOptions {
            attempts: 4096,
            texels_per_unit: 0.0,
            resolution: 0,
            max_chart_size: 1024,
            block_align: false,
            conservative: false,
            padding: 0,
        }
    }
}

#[derive(Debug)]
pub struct Chart<'a> {
    pub atlas_index: u32,
    pub indices: &'a [u32],
}

#[repr(C)]
#[derive(Debug)]
pub struct Vertex {
    pub atlas_index: u32,
    pub uv: [f32;2],
    pub xref: u32,
}

#[derive(Debug)]
pub struct Mesh<'a> {
    pub charts: Vec<Chart<'a>>, // need to translate Chart so it's owned
    pub indices: &'a [u32],
    pub vertices: &'a [Vertex],
}

#[derive(Debug)]
pub struct Xatlas {
    handle: *mut root::xatlas::Atlas,
}

unsafe extern "C" fn progress_cb(
    category: root::xatlas::ProgressCategory_Enum,
    progress: ::std::os::raw::c_int,
    user_data: *mut ::std::os::raw::c_void,
) {
    let cb: *mut &mut FnMut(ProgressCategory, i32) = unsafe { std::mem::transmute(user_data) };

    #[allow(non_snake_case)]
    (*cb)(match category {
        ProgressCategory_Enum_ComputeCharts => ProgressCategory::ComputeCharts,
        ProgressCategory_Enum_ParameterizeCharts => ProgressCategory::ParameterizeCharts,
        ProgressCategory_Enum_PackCharts => ProgressCategory::PackCharts,
        ProgressCategory_Enum_BuildOutputMeshes => ProgressCategory::BuildOutputMeshes,
    }, progress);
}

impl<'a> Xatlas {
    pub fn new() -> Self {
        Self {
            handle: unsafe { xatlas::Create() },
        }
    }

    pub fn add_mesh(&self, decl_param: &MeshDecl) {
        let decl = xatlas::MeshDecl {
            vertexCount: decl_param.vertex_count,
            vertexPositionData: decl_param.vertex_position_data.as_ptr() as _,
            vertexPositionStride: decl_param.vertex_position_stride,
            vertexNormalData: if decl_param.vertex_normal_data.is_empty() {
                std::ptr::null()
            } else {
                decl_param.vertex_normal_data.as_ptr() as _
            },
            vertexNormalStride: decl_param.vertex_normal_stride,
            vertexUvData: if decl_param.vertex_uv_data.is_empty() {
                std::ptr::null()
            } else {
                decl_param.vertex_uv_data.as_ptr() as _
            },
            vertexUvStride: decl_param.vertex_uv_stride,
            indexCount: decl_param.index_count,
            indexData: if decl_param.index_data.is_empty() {
                std::ptr::null()
            } else {
                decl_param.index_data.as_ptr() as _
            },
            indexOffset: decl_param.index_offset,
            indexFormat: match decl_param.index_format {
                IndexFormat::Uint16 => xatlas::IndexFormat_Enum_UInt16,
                IndexFormat::Uint32 => xatlas::IndexFormat_Enum_UInt32,
            },
            faceIgnoreData: if decl_param.face_ignore_data.is_empty() {
                std::ptr::null()
            } else {
                decl_param.face_ignore_data.as_ptr() as _
            },
        };

        unsafe {
            xatlas::AddMesh(self.handle, &decl);
        }
    }

    pub fn generate_simple(&self, chart_opts: ChartOptions, pack_opts: PackOptions){
        let chart_opts = chart_opts.convert();
        let pack_opts = pack_opts.convert();

        unsafe {
            xatlas::Generate(
                self.handle,
                chart_opts,
                None,
                pack_opts,
                None,
                std::ptr::null_mut(),
            )
        }
    }

    pub fn generate<F>(&self, chart_opts: ChartOptions, pack_opts: PackOptions, mut progress: F) 
    where
        F: FnMut(ProgressCategory, i32),
    {
        let chart_opts = chart_opts.convert();
        let pack_opts = pack_opts.convert();

        let mut cb: &mut FnMut(ProgressCategory, i32) = &mut progress;
        let cb = &mut cb as *mut &mut FnMut(ProgressCategory, i32) as *mut std::ffi::c_void;

        unsafe {
            xatlas::Generate(
                self.handle,
                chart_opts,
                None,
                pack_opts,
                Some(progress_cb),
                cb
            )
        }
    }

    /// Segments the meshes into charts (first step of `generate`). Added in the CSSM project's
    /// patched copy so that packing can be retried without recomputing charts.
    pub fn compute_charts(&self, chart_opts: ChartOptions) {
        unsafe { xatlas::ComputeCharts(self.handle, chart_opts.convert(), None, std::ptr::null_mut()) }
    }

    /// Parameterises the charts with xatlas' built-in method (second step of `generate`).
    pub fn parameterize_charts(&self) {
        unsafe { xatlas::ParameterizeCharts(self.handle, None, None, std::ptr::null_mut()) }
    }

    /// `compute_charts` reporting xatlas' progress (0 to 100) to `progress`, which xatlas may
    /// call from its worker threads, one call at a time (under its mutex). Added in the CSSM
    /// project's patched copy.
    pub fn compute_charts_with_progress(
        &self,
        chart_opts: ChartOptions,
        mut progress: impl FnMut(ProgressCategory, i32) + Send,
    ) {
        let mut cb: &mut dyn FnMut(ProgressCategory, i32) = &mut progress;
        let cb = &mut cb as *mut &mut dyn FnMut(ProgressCategory, i32) as *mut std::ffi::c_void;
        unsafe { xatlas::ComputeCharts(self.handle, chart_opts.convert(), Some(progress_cb), cb) }
    }

    /// `parameterize_charts` reporting xatlas' progress (0 to 100) to `progress`, called as
    /// by `compute_charts_with_progress`. Added in the CSSM project's patched copy.
    pub fn parameterize_charts_with_progress(
        &self,
        mut progress: impl FnMut(ProgressCategory, i32) + Send,
    ) {
        let mut cb: &mut dyn FnMut(ProgressCategory, i32) = &mut progress;
        let cb = &mut cb as *mut &mut dyn FnMut(ProgressCategory, i32) as *mut std::ffi::c_void;
        unsafe { xatlas::ParameterizeCharts(self.handle, None, Some(progress_cb), cb) }
    }

    /// Packs the charts into atlas pages (last step of `generate`); may be called again with
    /// other options.
    pub fn pack_charts(&self, pack_opts: PackOptions) {
        unsafe { xatlas::PackCharts(self.handle, pack_opts.convert(), None, std::ptr::null_mut()) }
    }

    /// Number of atlas pages after packing (0 when packing used no fixed resolution).
    pub fn atlas_count(&self) -> u32 {
        unsafe { (*self.handle).atlasCount }
    }

    /// Atlas width and height in texels after packing.
    pub fn size(&self) -> (u32, u32) {
        unsafe { ((*self.handle).width, (*self.handle).height) }
    }

    /// Texels per world unit used by the last packing.
    pub fn texels_per_unit(&self) -> f32 {
        unsafe { (*self.handle).texelsPerUnit }
    }

    pub fn meshes(&mut self) -> Vec<Mesh<'a>> {
        // shallow copy most data
        let mut meshes = vec![];

        let original_meshes = unsafe {
            std::slice::from_raw_parts((*self.handle).meshes, (*self.handle).meshCount as usize)
        };

        for original_mesh  in original_meshes {
            let mut charts = vec![];
            let original_charts = unsafe {
                std::slice::from_raw_parts(original_mesh.chartArray, original_mesh.chartCount as usize)
            };

            for original_chart in original_charts {
                charts.push(Chart{
                    atlas_index: original_chart.atlasIndex,
                    indices: unsafe {
                        std::slice::from_raw_parts(original_chart.indexArray, original_chart.indexCount as usize)
                    },
                })
            }

            meshes.push(Mesh {
                indices: unsafe {
                    std::slice::from_raw_parts(original_mesh.indexArray, original_mesh.indexCount as usize)
                },
                vertices: unsafe {
                    std::slice::from_raw_parts(original_mesh.vertexArray as *mut _ as *mut _, original_mesh.vertexCount as usize)
                },
                charts
            });
        }

        meshes
    }
}

impl<'a> Drop for Xatlas {
    fn drop(&mut self) {
        unsafe {
            xatlas::Destroy(self.handle);
        }
    }
}
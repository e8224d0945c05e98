//! The colour-class encoder ([`super::colour`]) as an ONNX graph omcl
//! writes itself, with its model card: any ONNX runtime (and omcl's
//! `--image-model`) can run it.
//!
//! Input `rgb`: `[1, 3, H, W]` float sRGB in [0, 1] (the card's mean 0,
//! std 1). Per pixel: sRGB to linear (`Where(x <= 0.04045, x / 12.92,
//! ((x + 0.055) / 1.055)^2.4)`), linear to XYZ over the D65 white (one
//! MatMul), Lab's `f` (`Where(t > (6/29)^3, t^(1/3), t / (3 (6/29)^2) +
//! 4/29)`), Lab (a MatMul and a bias), the score `2 lab . c - |c|^2` of
//! each centroid (MatMul, Sub), ArgMax, and the class's embedding
//! (Gather). Outputs: `features` `[1, H, W, F]` (the card's output, NHWC),
//! `lab` `[1, H, W, 3]` and `class` `[1, H, W]` (int64) for checking.

use super::card::{ImageSpec, Layout, ModelCard, ModelKind, Resize};
use super::colour::{ColourClasses, xyz_over_white};
use super::onnx_proto::{
    Dim, GraphProto, attr_int, attr_ints, data_type, float_tensor, model_bytes, node, value_info,
};
use super::preprocess::Filter;

/// ONNX operator set the graph uses (LessOrEqual needs 12).
pub const OPSET: i64 = 13;

/// The serialized ONNX model of `classes`.
pub fn colour_model(classes: &ColourClasses) -> Vec<u8> {
    let k = classes.len() as i64;
    let f = classes.dim as i64;
    const D: f32 = 6.0 / 29.0;
    // XYZ / white = lin . M^T: rows of the initializer are M's columns.
    let m = xyz_over_white();
    let m_t: Vec<f32> = (0..3).flat_map(|i| (0..3).map(move |j| m[j][i])).collect();
    // [fx fy fz] . A + b = [L a b].
    let a = vec![
        0.0, 500.0, 0.0, //
        116.0, -500.0, 200.0, //
        0.0, 0.0, -200.0,
    ];
    let two_c_t: Vec<f32> = (0..3)
        .flat_map(|j| classes.centroids.iter().map(move |c| 2.0 * c[j]))
        .collect();
    let c_norm2: Vec<f32> = classes
        .centroids
        .iter()
        .map(|c| c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        .collect();
    let scalar = |name: &str, v: f32| float_tensor(name, &[], vec![v]);
    let initializer = vec![
        scalar("c_lin_knee", 0.040_45),
        scalar("c_12_92", 12.92),
        scalar("c_0_055", 0.055),
        scalar("c_1_055", 1.055),
        scalar("c_2_4", 2.4),
        float_tensor("xyz_over_white_t", &[3, 3], m_t),
        scalar("c_f_knee", D * D * D),
        scalar("c_third", 1.0 / 3.0),
        scalar("c_f_slope_den", 3.0 * D * D),
        scalar("c_4_29", 4.0 / 29.0),
        float_tensor("lab_from_f", &[3, 3], a),
        float_tensor("lab_bias", &[3], vec![-16.0, 0.0, 0.0]),
        float_tensor("two_centroids_t", &[3, k], two_c_t),
        float_tensor("centroid_norm2", &[k], c_norm2),
        float_tensor("embeddings", &[k, f], classes.embeddings.clone()),
    ];
    let nodes = vec![
        node(
            "Transpose",
            &["rgb"],
            &["rgb_hwc"],
            vec![attr_ints("perm", &[0, 2, 3, 1])],
        ),
        node("Div", &["rgb_hwc", "c_12_92"], &["lin_low"], vec![]),
        node("Add", &["rgb_hwc", "c_0_055"], &["shifted"], vec![]),
        node("Div", &["shifted", "c_1_055"], &["scaled"], vec![]),
        node("Pow", &["scaled", "c_2_4"], &["lin_high"], vec![]),
        node(
            "LessOrEqual",
            &["rgb_hwc", "c_lin_knee"],
            &["is_low"],
            vec![],
        ),
        node(
            "Where",
            &["is_low", "lin_low", "lin_high"],
            &["linear"],
            vec![],
        ),
        node("MatMul", &["linear", "xyz_over_white_t"], &["t"], vec![]),
        node("Pow", &["t", "c_third"], &["f_high"], vec![]),
        node("Div", &["t", "c_f_slope_den"], &["f_slope"], vec![]),
        node("Add", &["f_slope", "c_4_29"], &["f_low"], vec![]),
        node("Greater", &["t", "c_f_knee"], &["is_high"], vec![]),
        node("Where", &["is_high", "f_high", "f_low"], &["f"], vec![]),
        node("MatMul", &["f", "lab_from_f"], &["lab_nobias"], vec![]),
        node("Add", &["lab_nobias", "lab_bias"], &["lab"], vec![]),
        node("MatMul", &["lab", "two_centroids_t"], &["dot2"], vec![]),
        node("Sub", &["dot2", "centroid_norm2"], &["score"], vec![]),
        node(
            "ArgMax",
            &["score"],
            &["class"],
            vec![attr_int("axis", 3), attr_int("keepdims", 0)],
        ),
        node(
            "Gather",
            &["embeddings", "class"],
            &["features"],
            vec![attr_int("axis", 0)],
        ),
    ];
    let (h, w) = (Dim::Named("height"), Dim::Named("width"));
    let graph = GraphProto {
        node: nodes,
        name: "omcl_colour_classes".into(),
        initializer,
        doc_string: String::new(),
        input: vec![value_info(
            "rgb",
            data_type::FLOAT,
            &[Dim::Fixed(1), Dim::Fixed(3), h.clone(), w.clone()],
        )],
        output: vec![
            value_info(
                "features",
                data_type::FLOAT,
                &[Dim::Fixed(1), h.clone(), w.clone(), Dim::Fixed(f)],
            ),
            value_info(
                "lab",
                data_type::FLOAT,
                &[Dim::Fixed(1), h.clone(), w.clone(), Dim::Fixed(3)],
            ),
            value_info("class", data_type::INT64, &[Dim::Fixed(1), h, w]),
        ],
        value_info: Vec::new(),
    };
    model_bytes(
        graph,
        OPSET,
        "omcl colour classes: sRGB -> CIE Lab (D65) -> nearest of K k-means centroids -> the \
         class's unit embedding. Not open-vocabulary: no words map to these features.",
    )
}

/// The model card of a colour-class model named `name`: NCHW input in
/// [0, 1], NHWC `features` output, the image resized to `width` x
/// `height` with Pillow's box filter (area averaging) first.
pub fn colour_card(classes: &ColourClasses, name: &str, width: u32, height: u32) -> ModelCard {
    ModelCard {
        kind: ModelKind::Image,
        name: name.into(),
        feature_dim: classes.dim,
        normalize: true,
        image: Some(ImageSpec {
            input: Some("rgb".into()),
            output: Some("features".into()),
            layout: Layout::Nchw,
            output_layout: Layout::Nhwc,
            resize: Resize::Fixed { width, height },
            filter: Filter::Box,
            center_crop: None,
            mean: [0.0; 3],
            std: [1.0; 3],
            window: None,
        }),
        text: None,
        point: None,
    }
}

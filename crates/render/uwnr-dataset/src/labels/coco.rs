//! COCO instances files: read and checked once, then every annotation of a clean image carried
//! to each of its renders (new ids, the render's file name and size; boxes, polygons, RLE masks,
//! keypoints and areas through the image's [`Fit`]).
//!
//! What is wrong with the file as a whole (not JSON, no `images`, an annotation of an image that
//! is not listed, a category that does not exist, duplicate ids) refuses the run with an error
//! naming the file and the entry. What is malformed in one image's labels (an odd-length
//! polygon, a negative box size, an RLE mask of another size, the listed size differing from the
//! file's) makes that image's pairs fail, listed in `failed.jsonl` with the file and the
//! annotation id; the run goes on. Geometry past the edge and degenerate shapes follow the
//! [`super::rules`]: clipped, or dropped and counted.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use serde_json::{Map, Value, json};

use super::geometry::Fit;
use super::rules::{Drop, DropCounts};

mod fit;

/// A checked COCO file.
#[derive(Debug)]
pub struct CocoFile {
    pub path: PathBuf,
    /// `info`, `licenses` and `categories` as given (`null` when absent).
    pub info: Value,
    pub licenses: Value,
    pub categories: Value,
    images: Vec<ImageEntry>,
    /// Annotations of each image, in file order, as given.
    annotations: Vec<Vec<Map<String, Value>>>,
}

#[derive(Debug)]
struct ImageEntry {
    id: Value,
    file_name: String,
    width: usize,
    height: usize,
    /// The entry's fields that stay true for its renders (`license`, `date_captured`).
    keep: Map<String, Value>,
}

fn err(path: &Path, at: &str, what: impl std::fmt::Display) -> String {
    format!("{}: {at}: {what}", path.display())
}

impl CocoFile {
    /// Parses and checks a COCO instances file.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Self, String> {
        let root: Value = serde_json::from_slice(bytes)
            .map_err(|e| format!("{}: not a JSON file: {e}", path.display()))?;
        let Value::Object(mut root) = root else {
            return Err(format!(
                "{}: not a COCO file: the top level is not an object",
                path.display()
            ));
        };
        for key in ["images", "annotations", "categories"] {
            if !root.get(key).is_some_and(Value::is_array) {
                return Err(format!(
                    "{}: not a COCO instances file: no \"{key}\" list",
                    path.display()
                ));
            }
        }
        // The lists are moved out of the parsed file, not copied: COCO files run to hundreds of
        // megabytes.
        let mut take = |key: &str| match root.remove(key) {
            Some(Value::Array(v)) => v,
            _ => Vec::new(),
        };
        let (images_v, anns_v, cats) = (take("images"), take("annotations"), take("categories"));

        let mut categories = HashSet::new();
        for (n, c) in cats.iter().enumerate() {
            let id = c
                .get("id")
                .and_then(Value::as_i64)
                .ok_or_else(|| err(path, &format!("categories[{n}]"), "no integer \"id\""))?;
            if !categories.insert(id) {
                return Err(err(
                    path,
                    &format!("categories[{n}]"),
                    format!("category id {id} is listed twice"),
                ));
            }
        }

        let mut images = Vec::with_capacity(images_v.len());
        let mut by_id: HashMap<i64, usize> = HashMap::new();
        for (n, v) in images_v.into_iter().enumerate() {
            let at = format!("images[{n}]");
            let Value::Object(mut entry) = v else {
                return Err(err(path, &at, "not an object"));
            };
            let id = entry
                .get("id")
                .and_then(Value::as_i64)
                .ok_or_else(|| err(path, &at, "no integer \"id\""))?;
            let file_name = entry
                .get("file_name")
                .and_then(Value::as_str)
                .ok_or_else(|| err(path, &at, format!("image {id} has no \"file_name\"")))?
                .replace('\\', "/");
            let dim = |key: &str| {
                entry
                    .get(key)
                    .and_then(Value::as_u64)
                    .filter(|&d| d > 0)
                    .map(|d| d as usize)
                    .ok_or_else(|| err(path, &at, format!("image {id} has no positive \"{key}\"")))
            };
            let (width, height) = (dim("width")?, dim("height")?);
            if by_id.insert(id, images.len()).is_some() {
                return Err(err(path, &at, format!("image id {id} is listed twice")));
            }
            let keep = ["license", "date_captured"]
                .into_iter()
                .filter_map(|k| entry.remove(k).map(|v| (k.to_string(), v)))
                .collect();
            images.push(ImageEntry {
                id: json!(id),
                file_name,
                width,
                height,
                keep,
            });
        }

        let mut annotations: Vec<Vec<Map<String, Value>>> = vec![Vec::new(); images.len()];
        let mut ann_ids = HashSet::new();
        for (n, v) in anns_v.into_iter().enumerate() {
            let at = format!("annotations[{n}]");
            let Value::Object(a) = v else {
                return Err(err(path, &at, "not an object"));
            };
            let id = a
                .get("id")
                .and_then(Value::as_i64)
                .ok_or_else(|| err(path, &at, "no integer \"id\""))?;
            let at = format!("annotation id {id} ({at})");
            if !ann_ids.insert(id) {
                return Err(err(path, &at, "the id is used twice"));
            }
            let image_id = a
                .get("image_id")
                .and_then(Value::as_i64)
                .ok_or_else(|| err(path, &at, "no integer \"image_id\""))?;
            let &image = by_id.get(&image_id).ok_or_else(|| {
                err(
                    path,
                    &at,
                    format!("refers to image {image_id}, which \"images\" does not list"),
                )
            })?;
            let category = a
                .get("category_id")
                .and_then(Value::as_i64)
                .ok_or_else(|| err(path, &at, "no integer \"category_id\""))?;
            if !categories.contains(&category) {
                return Err(err(
                    path,
                    &at,
                    format!("category {category} is not in \"categories\""),
                ));
            }
            annotations[image].push(a);
        }
        let mut field = |k: &str| root.remove(k).unwrap_or(Value::Null);
        Ok(Self {
            path: path.to_path_buf(),
            info: field("info"),
            licenses: field("licenses"),
            categories: Value::Array(cats),
            images,
            annotations,
        })
    }

    /// For each clean image, the index of its entry: matched by the path below the clean folder
    /// it was found in (`file_name` as COCO writes it, e.g. `train/0001.jpg`), else by the file
    /// name alone when exactly one entry has it.
    #[must_use]
    pub fn match_images(&self, rel_paths: &[String]) -> Vec<Option<usize>> {
        let by_path: HashMap<&str, usize> = self
            .images
            .iter()
            .enumerate()
            .map(|(i, e)| (e.file_name.as_str(), i))
            .collect();
        let mut by_name: HashMap<&str, Vec<usize>> = HashMap::new();
        for (i, e) in self.images.iter().enumerate() {
            let base = e.file_name.rsplit('/').next().unwrap_or(&e.file_name);
            by_name.entry(base).or_default().push(i);
        }
        rel_paths
            .iter()
            .map(|rel| {
                by_path.get(rel.as_str()).copied().or_else(|| {
                    let base = rel.rsplit('/').next().unwrap_or(rel);
                    match by_name.get(base).map(Vec::as_slice) {
                        Some([one]) => Some(*one),
                        _ => None,
                    }
                })
            })
            .collect()
    }

    /// Number of images listed.
    #[must_use]
    pub fn image_count(&self) -> usize {
        self.images.len()
    }

    /// The fingerprint of entry `image` with its annotations and the first annotation id its
    /// pairs take: what its pairs' labels depend on.
    #[must_use]
    pub fn image_fingerprint(&self, image: usize, first_id: u64) -> String {
        let e = &self.images[image];
        let v = json!({
            "id": e.id, "file_name": e.file_name, "width": e.width, "height": e.height,
            "keep": e.keep, "annotations": self.annotations[image], "first_id": first_id,
        });
        uwnr_render::record::fingerprint(v.to_string().as_bytes())
    }

    /// Number of annotations of entry `image`.
    #[must_use]
    pub fn annotation_count(&self, image: usize) -> usize {
        self.annotations[image].len()
    }

    /// The annotations of entry `image` carried through `fit` (ids and image ids not yet set),
    /// with the image entry's fields to keep. Fails, naming the annotation, when a label does not
    /// fit its image.
    pub fn fitted(
        &self,
        image: usize,
        actual: (usize, usize),
        fit: &Fit,
    ) -> Result<FittedImage, String> {
        let e = &self.images[image];
        let at = |what: String| {
            format!(
                "{}: image {} ({}): {what}",
                self.path.display(),
                e.id,
                e.file_name
            )
        };
        if (e.width, e.height) != actual {
            return Err(at(format!(
                "the file lists {}x{}, the image is {}x{} (an EXIF rotation?)",
                e.width, e.height, actual.0, actual.1
            )));
        }
        let mut annotations = Vec::with_capacity(self.annotations[image].len());
        for a in &self.annotations[image] {
            let id = a.get("id").cloned().unwrap_or(Value::Null);
            let fitted = fit::fit_annotation(a, (e.width, e.height), fit)
                .map_err(|reason| at(format!("annotation id {id}: {reason}")))?;
            annotations.push(fitted);
        }
        Ok(FittedImage {
            source_id: e.id.clone(),
            source_file_name: e.file_name.clone(),
            keep: e.keep.clone(),
            annotations,
        })
    }
}

/// One image's labels carried to its pairs; [`FittedImage::pair`] gives each pair its ids.
#[derive(Clone, Debug)]
pub struct FittedImage {
    source_id: Value,
    source_file_name: String,
    keep: Map<String, Value>,
    /// `Err` where the annotation was dropped (its id is then skipped).
    annotations: Vec<Result<Map<String, Value>, Drop>>,
}

impl FittedImage {
    /// The annotations dropped, by reason (the same for every pair of the image).
    #[must_use]
    pub fn dropped(&self) -> DropCounts {
        let mut out = DropCounts::default();
        for a in &self.annotations {
            if let Err(d) = a {
                out.add(*d);
            }
        }
        out
    }

    /// The pair's labels file: `{"image": {...}, "annotations": [...]}` with the image id
    /// `index + 1` and annotation ids from `first_id` on, in the source's order.
    #[must_use]
    pub fn pair(&self, id: &str, index: u64, size: (usize, usize), first_id: u64) -> Value {
        let image_id = index + 1;
        let mut image = Map::new();
        image.insert("id".into(), json!(image_id));
        image.insert("file_name".into(), json!(format!("underwater/{id}.png")));
        image.insert("width".into(), json!(size.0));
        image.insert("height".into(), json!(size.1));
        image.insert("clean_file_name".into(), json!(format!("clean/{id}.png")));
        image.insert("source_id".into(), self.source_id.clone());
        image.insert("source_file_name".into(), json!(self.source_file_name));
        for (k, v) in &self.keep {
            image.insert(k.clone(), v.clone());
        }
        let annotations: Vec<Value> = self
            .annotations
            .iter()
            .enumerate()
            .filter_map(|(j, a)| {
                let mut a = a.clone().ok()?;
                a.insert("id".into(), json!(first_id + j as u64));
                a.insert("image_id".into(), json!(image_id));
                Some(Value::Object(a))
            })
            .collect();
        json!({ "image": image, "annotations": annotations })
    }
}

/// The whole COCO file of a dataset from its pairs' labels files, in pair order.
#[must_use]
pub fn assemble(info: &Value, licenses: &Value, categories: &Value, pairs: Vec<Value>) -> Value {
    let mut images = Vec::with_capacity(pairs.len());
    let mut annotations = Vec::new();
    for mut p in pairs {
        if let Some(i) = p.get_mut("image").map(Value::take) {
            images.push(i);
        }
        if let Some(Value::Array(a)) = p.get_mut("annotations").map(Value::take) {
            annotations.extend(a);
        }
    }
    let mut root = Map::new();
    if !info.is_null() {
        root.insert("info".into(), info.clone());
    }
    if !licenses.is_null() {
        root.insert("licenses".into(), licenses.clone());
    }
    root.insert("images".into(), Value::Array(images));
    root.insert("annotations".into(), Value::Array(annotations));
    root.insert("categories".into(), categories.clone());
    Value::Object(root)
}

#[cfg(test)]
mod tests {
    use super::fit::numbers;
    use super::*;
    use crate::labels::rle::{Mask, counts_from_string, counts_to_string};
    use crate::plan::Size;

    fn file(text: &str) -> Result<CocoFile, String> {
        CocoFile::parse(Path::new("instances.json"), text.as_bytes())
    }

    /// [`GOOD`] with annotation 72's mask: columns 60..140, rows 0..40 of the 400x200 image.
    fn good() -> Result<CocoFile, String> {
        let mut counts = vec![60 * 200];
        for _ in 60..140 {
            counts.extend([40, 160]);
        }
        *counts.last_mut().unwrap() += 260 * 200;
        file(&GOOD.replace("\"COUNTS\"", &json!(counts).to_string()))
    }

    const GOOD: &str = r#"{
        "info": {"description": "tiny"},
        "images": [
            {"id": 7, "file_name": "train/a.jpg", "width": 400, "height": 200, "license": 1,
             "coco_url": "http://example/a.jpg"},
            {"id": 8, "file_name": "b.jpg", "width": 100, "height": 100}
        ],
        "annotations": [
            {"id": 70, "image_id": 7, "category_id": 1, "bbox": [120, 20, 80, 80], "area": 6400,
             "iscrowd": 0, "segmentation": [[120, 20, 200, 20, 200, 100, 120, 100]],
             "keypoints": [130, 30, 2, 10, 10, 2, 0, 0, 0], "num_keypoints": 2},
            {"id": 71, "image_id": 7, "category_id": 2, "bbox": [0, 0, 90, 50], "area": 4500,
             "iscrowd": 0, "segmentation": [[0, 0, 90, 0, 90, 50, 0, 50]]},
            {"id": 72, "image_id": 7, "category_id": 2, "bbox": [60, 0, 80, 40], "area": 3200,
             "iscrowd": 1, "segmentation": {"size": [200, 400], "counts": "COUNTS"}},
            {"id": 80, "image_id": 8, "category_id": 1, "bbox": [0, 0, 10, 10], "area": 100}
        ],
        "categories": [{"id": 1, "name": "fish"}, {"id": 2, "name": "diver"}]
    }"#;

    #[test]
    fn annotations_follow_the_fit_and_get_new_ids() {
        let coco = good().unwrap();
        assert_eq!(
            coco.match_images(&["train/a.jpg".into(), "x/b.jpg".into(), "c.jpg".into()]),
            [Some(0), Some(1), None]
        );
        // 400x200 to 100x100: scale 0.5, 50 px cropped on each side.
        let fit = Fit::new(
            (400, 200),
            Size::Fixed {
                width: 100,
                height: 100,
            },
        );
        let f = coco.fitted(0, (400, 200), &fit).unwrap();
        let pair = f.pair("a_1", 3, (100, 100), 11);
        assert_eq!(pair["image"]["id"], 4);
        assert_eq!(pair["image"]["file_name"], "underwater/a_1.png");
        assert_eq!(pair["image"]["source_id"], 7);
        assert_eq!(pair["image"]["license"], 1);
        assert!(pair["image"].get("coco_url").is_none());
        let anns = pair["annotations"].as_array().unwrap();
        // 71 lies in the cropped-off strip: gone, its id (12) skipped.
        assert_eq!(anns.len(), 2);
        let a = &anns[0];
        assert_eq!(
            (a["id"].as_u64(), a["image_id"].as_u64()),
            (Some(11), Some(4))
        );
        assert_eq!(a["bbox"], json!([10.0, 10.0, 40.0, 40.0]));
        assert_eq!(a["area"], json!(1600.0));
        assert_eq!(
            a["segmentation"],
            json!([[10.0, 10.0, 50.0, 10.0, 50.0, 50.0, 10.0, 50.0]])
        );
        // Keypoint 2 fell in the crop: zeroed, and num_keypoints counts what is left.
        assert_eq!(
            a["keypoints"],
            json!([15.0, 15.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        );
        assert_eq!(a["num_keypoints"], 1);
        // 72, an RLE mask across the crop's edge: resampled, cut, area counted in pixels.
        let r = &anns[1];
        assert_eq!(r["id"], 13);
        assert_eq!(r["segmentation"]["size"], json!([100, 100]));
        let counts: Vec<u64> = r["segmentation"]["counts"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        let m = Mask::from_counts(100, 100, &counts).unwrap();
        assert_eq!(r["area"].as_f64().unwrap() as usize, m.area());
        assert!(m.area() > 0);
        let b: Vec<f64> = numbers(&r["bbox"]).unwrap();
        let mb = m.bbox();
        assert!(
            b[0] >= mb[0] - 1e-9 && b[0] + b[2] <= mb[0] + mb[2] + 1e-9,
            "{b:?} {mb:?}"
        );
    }

    #[test]
    fn identity_fits_copy_annotations_unchanged() {
        let coco = good().unwrap();
        let fit = Fit::new((100, 100), Size::Native);
        let f = coco.fitted(1, (100, 100), &fit).unwrap();
        let pair = f.pair("b_0", 0, (100, 100), 1);
        let a = &pair["annotations"][0];
        assert_eq!(a["bbox"], json!([0, 0, 10, 10]));
        assert_eq!(a["area"], json!(100));
    }

    #[test]
    fn bad_files_are_refused_naming_the_entry() {
        let e = file("{\"images\": [").unwrap_err();
        assert!(e.starts_with("instances.json: not a JSON file"), "{e}");
        let e = file(r#"{"images": [], "annotations": []}"#).unwrap_err();
        assert!(e.contains("no \"categories\" list"), "{e}");
        let e = file(
            r#"{"images": [{"id": 1, "file_name": "a.jpg", "width": 4, "height": 4}],
            "annotations": [{"id": 5, "image_id": 2, "category_id": 1, "bbox": [0,0,1,1]}],
            "categories": [{"id": 1}]}"#,
        )
        .unwrap_err();
        assert!(
            e.contains("annotation id 5") && e.contains("image 2"),
            "{e}"
        );
        let e = file(
            r#"{"images": [{"id": 1, "file_name": "a.jpg", "width": 4, "height": 4}],
            "annotations": [{"id": 5, "image_id": 1, "category_id": 9, "bbox": [0,0,1,1]}],
            "categories": [{"id": 1}]}"#,
        )
        .unwrap_err();
        assert!(e.contains("category 9"), "{e}");
        let e = file(
            r#"{"images": [{"id": 1, "file_name": "a.jpg", "width": 4}],
            "annotations": [], "categories": []}"#,
        )
        .unwrap_err();
        assert!(e.contains("images[0]") && e.contains("height"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }

    #[test]
    fn labels_that_do_not_fit_their_image_fail_that_image() {
        // A box past the edge is clipped, not refused (19 px past, at 40x40 -> 20x20).
        let coco = file(
            r#"{"images": [{"id": 1, "file_name": "a.jpg", "width": 40, "height": 40}],
            "annotations": [{"id": 5, "image_id": 1, "category_id": 1, "bbox": [30, 30, 29, 5],
              "area": 145}],
            "categories": [{"id": 1}]}"#,
        )
        .unwrap();
        let fit = Fit::new(
            (40, 40),
            Size::Fixed {
                width: 20,
                height: 20,
            },
        );
        let pair = coco
            .fitted(0, (40, 40), &fit)
            .unwrap()
            .pair("a_0", 0, (20, 20), 1);
        assert_eq!(
            pair["annotations"][0]["bbox"],
            json!([15.0, 15.0, 5.0, 2.5])
        );
        assert_eq!(pair["annotations"][0]["area"], json!(12.5));
        let e = coco.fitted(0, (40, 30), &fit).unwrap_err();
        assert!(e.contains("lists 40x40, the image is 40x30"), "{e}");
        let coco = file(
            r#"{"images": [{"id": 1, "file_name": "a.jpg", "width": 40, "height": 40}],
            "annotations": [{"id": 6, "image_id": 1, "category_id": 1, "bbox": [0, 0, 2, 2],
              "segmentation": {"size": [20, 20], "counts": [400]}}],
            "categories": [{"id": 1}]}"#,
        )
        .unwrap();
        let e = coco.fitted(0, (40, 40), &fit).unwrap_err();
        assert!(
            e.contains("annotation id 6") && e.contains("RLE mask is 20x20"),
            "{e}"
        );
    }

    #[test]
    fn compressed_rle_stays_compressed() {
        let mask = Mask::from_counts(4, 4, &[5, 2, 2, 2, 5]).unwrap();
        let text = format!(
            r#"{{"images": [{{"id": 1, "file_name": "a.jpg", "width": 4, "height": 4}}],
            "annotations": [{{"id": 1, "image_id": 1, "category_id": 1, "bbox": [1, 1, 2, 2], "area": 4,
              "iscrowd": 0, "segmentation": {{"size": [4, 4], "counts": "{}"}}}}],
            "categories": [{{"id": 1}}]}}"#,
            counts_to_string(&mask.counts())
        );
        let coco = file(&text).unwrap();
        let fit = Fit::new(
            (4, 4),
            Size::Fixed {
                width: 16,
                height: 16,
            },
        );
        let pair = coco
            .fitted(0, (4, 4), &fit)
            .unwrap()
            .pair("a_0", 0, (16, 16), 1);
        let a = &pair["annotations"][0];
        let s = a["segmentation"]["counts"].as_str().unwrap();
        let m = Mask::from_counts(16, 16, &counts_from_string(s).unwrap()).unwrap();
        assert_eq!(m.area(), 64);
        assert_eq!(a["area"], json!(64.0));
        assert_eq!(a["bbox"], json!([4.0, 4.0, 8.0, 8.0]));
    }

    #[test]
    fn assembled_files_list_every_pair() {
        let coco = good().unwrap();
        let fit = Fit::new((100, 100), Size::Native);
        let f = coco.fitted(1, (100, 100), &fit).unwrap();
        let pairs = vec![
            f.pair("b_0", 2, (100, 100), 1),
            f.pair("b_1", 3, (100, 100), 2),
        ];
        let all = assemble(&coco.info, &coco.licenses, &coco.categories, pairs);
        assert_eq!(all["images"].as_array().unwrap().len(), 2);
        assert_eq!(all["annotations"][1]["id"], 2);
        assert_eq!(all["annotations"][1]["image_id"], 4);
        assert_eq!(all["categories"][1]["name"], "diver");
        assert!(all.get("licenses").is_none());
    }
}

"""Unreal Engine 5.3 Python API names that coastforge's build_level.py may use, each with the documentation
page it was checked against (dev.epicgames.com Python API / C++ API / Blueprint API pages; C++ functions are
exposed to Python in snake_case, e.g. ``SpawnActorFromObject`` → ``spawn_actor_from_object``).

The recording stand-in for the ``unreal`` module (tests/unreal_stub.py) rejects every name not listed here.
Keys: ``"name"`` for module-level functions and classes, ``"Class.member"`` for methods, properties and
enum values; ``"Class.editor_property:name"`` for names passed to get/set_editor_property.
"""

PY = "https://dev.epicgames.com/documentation/en-us/unreal-engine/python-api"
CPP = "https://dev.epicgames.com/documentation/unreal-engine/API"
BP = "https://dev.epicgames.com/documentation/unreal-engine/BlueprintAPI"

API: dict[str, str] = {
    # module level
    "get_editor_subsystem": f"{PY}/module/unreal?application_version=5.1",
    # subsystems
    "LevelEditorSubsystem": f"{PY}/class/LevelEditorSubsystem?application_version=5.1",
    "LevelEditorSubsystem.new_level_from_template":
        f"{CPP}/Plugins/EditorScriptingUtilities/UEditorLevelLibrary/NewLevelFromTemplate?application_version=5.3"
        " (deprecated there: 'Use the function in Level Editor Subsystem')",
    "LevelEditorSubsystem.load_level": f"{PY}/class/LevelEditorSubsystem?application_version=5.1",
    "LevelEditorSubsystem.save_current_level":
        f"{CPP}/Editor/LevelEditor/ULevelEditorSubsystem/SaveCurrentLevel?application_version=5.4",
    "EditorActorSubsystem": f"{CPP}/Editor/UnrealEd/Subsystems/UEditorActorSubsystem?application_version=5.3",
    "EditorActorSubsystem.spawn_actor_from_object":
        f"{CPP}/Editor/UnrealEd/Subsystems/UEditorActorSubsystem/SpawnActorFromObject?application_version=5.3",
    "EditorActorSubsystem.spawn_actor_from_class":
        f"{CPP}/Editor/UnrealEd/Subsystems/UEditorActorSubsystem/SpawnActorFromClass?application_version=5.3",
    "EditorActorSubsystem.get_all_level_actors": f"{PY}/class/EditorActorSubsystem?application_version=5.1",
    "EditorActorSubsystem.destroy_actor":
        f"{CPP}/Editor/UnrealEd/Subsystems/UEditorActorSubsystem/DestroyActor?application_version=5.4",
    "UnrealEditorSubsystem": f"{PY}/class/UnrealEditorSubsystem?application_version=5.1",
    "UnrealEditorSubsystem.get_editor_world": f"{PY}/class/UnrealEditorSubsystem?application_version=5.1",
    # assets
    "EditorAssetSubsystem": f"{CPP}/Editor/UnrealEd/Subsystems/UEditorAssetSubsystem/DoesAssetExist?application_version=5.3",
    "EditorAssetSubsystem.does_asset_exist":
        f"{CPP}/Editor/UnrealEd/Subsystems/UEditorAssetSubsystem/DoesAssetExist?application_version=5.3",
    "StaticMesh": f"{PY}/class/StaticMesh?application_version=5.1",
    "EditorAssetLibrary": f"{CPP}/Plugins/EditorScriptingUtilities/UEditorAssetLibrary/LoadAsset",
    "EditorAssetLibrary.does_asset_exist":
        f"{CPP}/Plugins/EditorScriptingUtilities/UEditorAssetLibrary/DoesAssetExist?application_version=5.3",
    "EditorAssetLibrary.load_asset": f"{CPP}/Plugins/EditorScriptingUtilities/UEditorAssetLibrary/LoadAsset",
    "EditorAssetLibrary.list_assets":
        f"{CPP}/Plugins/EditorScriptingUtilities/UEditorAssetLibrary/ListAssets?application_version=5.3"
        " (ListAssets(DirectoryPath, bRecursive=true, bIncludeFolder=false) -> object paths)",
    "AssetImportTask": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:filename": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:destination_path": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:destination_name": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:automated": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:replace_existing": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:save": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetImportTask.editor_property:imported_object_paths": f"{PY}/class/AssetImportTask?application_version=5.1",
    "AssetToolsHelpers": f"{PY}/class/AssetToolsHelpers?application_version=5.1",
    "AssetToolsHelpers.get_asset_tools": f"{PY}/class/AssetToolsHelpers?application_version=5.1",
    "AssetTools.import_asset_tasks": f"{CPP}/Developer/AssetTools/IAssetTools/ImportAssetTasks?application_version=5.1",
    # render targets and textures
    "RenderingLibrary": f"{PY}/class/RenderingLibrary?application_version=5.1",
    "RenderingLibrary.create_render_target2d": f"{PY}/class/RenderingLibrary?application_version=5.1",
    "RenderingLibrary.import_file_as_texture2d":
        f"{CPP}/Runtime/Engine/Kismet/UKismetRenderingLibrary/ImportFileAsTexture2D?application_version=5.2",
    "RenderingLibrary.begin_draw_canvas_to_render_target": f"{PY}/class/RenderingLibrary?application_version=5.1",
    "RenderingLibrary.end_draw_canvas_to_render_target": f"{PY}/class/RenderingLibrary?application_version=5.1",
    "RenderingLibrary.read_render_target_raw_pixel":
        f"{CPP}/Runtime/Engine/Kismet/UKismetRenderingLibrary/ReadRenderTargetRawPixel?application_version=5.3"
        " (X, Y, bNormalize = true -> FLinearColor)",
    "TextureRenderTargetFormat": f"{PY}/class/TextureRenderTargetFormat?application_version=5.1",
    "TextureRenderTargetFormat.RTF_RGBA8": f"{PY}/class/TextureRenderTargetFormat?application_version=5.1",
    "TextureFilter": f"{PY}/class/TextureFilter?application_version=5.1",
    "TextureFilter.TF_NEAREST": f"{PY}/class/TextureFilter?application_version=5.1",
    "Texture.editor_property:srgb": f"{PY}/class/TextureRenderTarget?application_version=5.3 (Texture properties)",
    "Texture.editor_property:filter": f"{PY}/class/TextureRenderTarget?application_version=5.3 (Texture properties)",
    "Canvas.draw_texture": f"{PY}/class/Canvas?application_version=5.1",
    "BlendMode": f"{BP}/HUD/DrawTexture (Blend Mode input: EBlendMode)",
    "BlendMode.BLEND_OPAQUE": f"{BP}/HUD/DrawTexture (EBlendMode)",
    # landscape
    "LandscapeProxy": f"{CPP}/Runtime/Landscape/ALandscapeProxy/LandscapeImportHeightmapFromRend-?application_version=5.4",
    "LandscapeProxy.landscape_import_heightmap_from_render_target":
        f"{CPP}/Runtime/Landscape/ALandscapeProxy/LandscapeImportHeightmapFromRend-?application_version=5.4",
    "LandscapeProxy.landscape_export_heightmap_to_render_target":
        f"{CPP}/Runtime/Landscape/ALandscapeProxy?application_version=5.3 (LandscapeExportHeightmapToRenderTarget("
        "InRenderTarget, InExportHeightIntoRGChannel, InExportLandscapeProxies), BlueprintCallable)",
    "LandscapeProxy.landscape_import_weightmap_from_render_target":
        f"{CPP}/Runtime/Landscape/ALandscapeProxy/LandscapeImportWeightmapFromRend-?application_version=5.4",
    # actors
    "Actor.set_actor_scale3d": f"{BP}/Transformation/SetActorScale3D",
    "Actor.set_actor_location": f"{BP}/Transformation/SetActorLocation",
    "Actor.get_actor_location": f"{CPP}/Runtime/Engine/GameFramework/AActor/GetActorScale3D?application_version=5.4"
                                " (Transformation functions of AActor)",
    "Actor.set_folder_path": f"{BP}/EditorScripting/ActorEditing/SetFolderPath",
    "Actor.set_actor_label": f"{BP}/EditorScripting/ActorEditing/SetActorLabel",
    "Actor.get_actor_label": f"{BP}/EditorScripting/ActorEditing/GetActorLabel",
    "Actor.get_component_by_class": f"{BP}/Utilities/GetComponentByClass",
    "Actor.editor_property:root_component": f"{PY}/class/Actor?application_version=5.3 (root_component)",
    "SceneComponent": f"{PY}/class/SceneComponent?application_version=5.3",
    "SceneComponent.editor_property:mobility": f"{PY}/class/SceneComponent?application_version=5.3 (mobility)",
    "ComponentMobility": f"{PY}/class/ComponentMobility?application_version=5.3",
    "ComponentMobility.MOVABLE": f"{PY}/class/ComponentMobility?application_version=5.3",
    "Actor.editor_property:tags": f"{PY}/class/PCGComponent?application_version=5.3 (Actor/Component tags: Array[Name])",
    "Vector": f"{PY}/class/Vector?application_version=5.1",
    "Vector.z": f"{PY}/class/Vector?application_version=5.1",
    "Vector2D": f"{PY}/class/Vector2D?application_version=5.1",
    "Rotator": f"{PY}/class/Rotator?application_version=5.1 (Rotator(roll=0.0, pitch=0.0, yaw=0.0))",
    "LinearColor": f"{PY}/class/LinearColor?application_version=5.1",
    # PCG
    "PCGVolume": f"{CPP}/Plugins/PCG/APCGVolume?application_version=5.3",
    "PCGComponent": f"{PY}/class/PCGComponent?application_version=5.3",
    "PCGComponent.set_graph": f"{CPP}/Plugins/PCG/UPCGComponent/SetGraph?application_version=5.3",
    "PCGComponent.generate": f"{CPP}/Plugins/PCG/UPCGComponent/Generate/2?application_version=5.3",
}

# UE 5.3 class hierarchy used by the stand-in to resolve inherited members
BASES: dict[str, str] = {
    "StaticMeshActor": "Actor", "LandscapeProxy": "Actor", "Landscape": "LandscapeProxy", "PCGVolume": "Actor",
    "Texture2D": "Texture", "TextureRenderTarget2D": "Texture",
}
